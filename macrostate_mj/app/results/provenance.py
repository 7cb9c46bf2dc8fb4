"""Where each committed results folder comes from, and whether it is a result or a smoke test.

`results/index.toml` gives per folder its `command`, `kind` (a sentence beginning "result" or
"smoke"), `units` (how many independent seeds, folds or datasets its figures average) and, where
they apply, `chosen_on_scored` (a setting chosen on the data the folder is scored on),
`resumed_from` (a cache or checkpoint it continued), `copied` (files copied in rather than
written by the command) and `code` (made by earlier code: what today's code gives instead).
One definition holds the labels honest (`RESULT_RULE`).
"""

from __future__ import annotations

import tomllib
from pathlib import Path

from macrostate_mj.core.errors import UserError

MIN_UNITS = 3
RESULT_RULE = (f"A result has at least {MIN_UNITS} independent seeds, folds or datasets, and "
               "none of its settings was chosen on the data it is scored on; anything else is "
               "a smoke test: a direction, not a measurement.")
DISCLOSED = ("chosen_on_scored", "resumed_from", "copied", "code", "unchecked")


def read_index(results: Path) -> dict[str, dict]:
    """`results/index.toml`, checked to hold a command, a kind and units per folder."""
    try:
        index = tomllib.loads((results / "index.toml").read_text())
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise UserError(f"cannot read {results / 'index.toml'}: {exc}") from exc
    for name, entry in index.items():
        missing = {"command", "kind", "units"} - set(entry)
        if missing:
            raise UserError(f"{results / 'index.toml'} [{name}] lacks {sorted(missing)}: give "
                            "each folder its command, kind and independent units")
    return index


def is_result(entry: dict) -> bool:
    """What `RESULT_RULE` says of one index entry."""
    return int(entry["units"]) >= MIN_UNITS and not entry.get("chosen_on_scored")


def smoke_folders(results: Path) -> frozenset[str]:
    """The folders the rule calls smoke."""
    return frozenset(name for name, entry in read_index(results).items()
                     if not is_result(entry))


def disclosures(entry: dict) -> list[str]:
    """What a reader must see beside a folder's numbers: resumes, copies, earlier code and
    settings chosen on the scored data, each as the index words it."""
    labels = {"chosen_on_scored": "chosen on the scored data", "resumed_from": "resumed from",
              "copied": "copied", "code": "earlier code",
              "unchecked": "not checked against a manifest"}
    return [f"{labels[key]}: {entry[key]}" for key in DISCLOSED if entry.get(key)]
