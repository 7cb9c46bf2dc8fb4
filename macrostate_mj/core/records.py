"""A typed results record: what a run's results file holds, declared once beside its writer.

An experiment (or a command) that writes `results.json` declares it as a frozen dataclass
subclassing `Record`: each top-level key a field, `UNIT` what in it is independent (a seed
with its own data and test, a cross-validated fold, a split, a dataset, a test instance), and
`VERSION`. It writes through `write` and everything that shows its numbers (the docs' tables,
the claims' sources, beside it) reads through `read`, so a renamed key fails where it is
written, in the experiment's own test, not on a page. Nested values stay JSON (dicts, lists):
the type fixes the file's shape at its top level and names its unit.

`UNIT` is the experiment's default; a folder's entry of `results/index.toml` may declare
another (a cross-validated run's folds, a map's test instances), and the claims and pages read
that first.

A field whose default is `None` and whose metadata says `OPTIONAL` is a key the file holds only
in some runs (a profile's extra table): left out when `None`, read as `None` where absent, so
the records of earlier runs read with the same type.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any, ClassVar, Self

from macrostate_mj.core.errors import UserError
from macrostate_mj.core.io import write_json_atomic

OPTIONAL = {"optional": True}       # a field's metadata: the key is absent from some runs
UNITS = ("seed", "fold", "split", "dataset", "test instance", "run")


class RecordError(UserError):
    """A results file that is not the record its type declares (named, with the fix)."""


@dataclass(frozen=True)
class Record:
    """The base of every results record (see the module docstring)."""

    FILE: ClassVar[str] = "results.json"
    UNIT: ClassVar[str] = "seed"
    VERSION: ClassVar[int] = 1

    def __init_subclass__(cls, **kw: Any) -> None:
        super().__init_subclass__(**kw)
        if cls.UNIT not in UNITS:
            raise TypeError(f"{cls.__qualname__}.UNIT {cls.UNIT!r} is not one of {UNITS}")

    def as_json(self) -> dict[str, Any]:
        """The file's object: every field by name, optional ones only when set."""
        return {f.name: getattr(self, f.name) for f in fields(self)
                if not (f.metadata.get("optional") and getattr(self, f.name) is None)}

    def write(self, out: Path) -> Path:
        """Write the record into folder `out` (atomically); its path."""
        path = Path(out) / self.FILE
        write_json_atomic(path, self.as_json())
        return path

    @classmethod
    def described(cls) -> dict[str, Any]:
        """What a manifest says of the record: its type, version and unit."""
        return {"type": f"{cls.__module__}.{cls.__qualname__}", "version": cls.VERSION,
                "unit": cls.UNIT}

    @classmethod
    def of(cls, data: dict[str, Any], where: str = "a results file") -> Self:
        """The record a file's object holds, its keys checked against the fields."""
        names = {f.name: f for f in fields(cls)}
        unknown = sorted(set(data) - set(names))
        missing = sorted(n for n, f in names.items()
                         if n not in data and not f.metadata.get("optional"))
        if unknown or missing:
            raise RecordError(f"{where} is not a {cls.__qualname__} record (unknown keys "
                              f"{_few(unknown)}, missing {_few(missing)}): rerun the command "
                              "that wrote it")
        return cls(**data)

    @classmethod
    def read(cls, folder: Path) -> Self:
        """The record in `folder` (its `FILE`)."""
        path = Path(folder) / cls.FILE
        try:
            data = json.loads(path.read_text())
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise RecordError(f"cannot read {path}: {exc}; rerun the command that wrote "
                              "it") from exc
        return cls.of(data, str(path))


def _few(keys: list[str]) -> str:
    """Keys as an error line names them: the first five, and how many more."""
    if not keys:
        return "none"
    more = f" and {len(keys) - 5} more" if len(keys) > 5 else ""
    return f"{keys[:5]}{more}"
