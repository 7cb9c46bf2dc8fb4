"""The one registry of results sources: named functions that read the committed results and
return what a page shows (`Q`, `Paired`, `Table`) or what a claim judges (`Figure`).

A page names a source (``{n}`meanstd(srs_text/results.json, configs/x, .1f)` ``, ``{results-table}
srs_table(srs_text, head_cm)``) and so does a claim in `claims.toml` (``srs(srs_text, passive,
1.0000)``): both call `call`, which finds the name in `SOURCES`. An experiment's sources live
beside it (in its module, or its package's `tables.py`), read its results through its typed
record (`core.records.Record.read`) and register with `@source`; the generic ones here take a
file and a key path. `SOURCES` finds them all by the one discovery rule: it imports the modules
of the packages it names on first read.
"""

from __future__ import annotations

import contextlib
import json
import re
import statistics
from collections.abc import Callable, Iterator
from functools import cache
from pathlib import Path
from typing import TypeVar

from macrostate_mj.core.evidence import ClaimsError, Design, Figure, Paired, Q, dig
from macrostate_mj.core.records import Record
from macrostate_mj.core.registry import Registry
from macrostate_mj.core.run import MANIFEST
from macrostate_mj.core.stats import mean_std

R = TypeVar("R", bound=Record)
# where sources live: beside the experiments, use cases and bench that write what they read
PACKAGES = ("macrostate_mj.app.experiments", "macrostate_mj.app.usecases",
            "macrostate_mj.app.bench", "macrostate_mj.app.results")
SOURCES: Registry[Callable[..., object]] = Registry("results source", packages=PACKAGES,
                                                    deep=True)
# each experiment's record type by the experiment's name (`app.experiments.register` adds it)
RECORDS: Registry[type[Record]] = Registry("results record",
                                           packages=["macrostate_mj.app.experiments"])
_ROOTS: list[Path] = []          # the results folder being read (`reading`)


def source(fn: Callable[..., object]) -> Callable[..., object]:
    """Register `fn` under its own name as a source pages and claims may call."""
    return SOURCES.register(fn.__name__)(fn)


@contextlib.contextmanager
def reading(results: Path) -> Iterator[Path]:
    """Read the sources' files from the results folder `results` while inside."""
    _ROOTS.append(Path(results).resolve())
    try:
        yield _ROOTS[-1]
    finally:
        _ROOTS.pop()


def root() -> Path:
    if not _ROOTS:
        raise ClaimsError("no results folder is being read: call the sources inside "
                          "`reading(results)`")
    return _ROOTS[-1]


@cache
def read_path(file: Path) -> object:
    """A JSON (or JSON lines, as a list) file, read once."""
    if not file.is_file():
        raise ClaimsError(f"{file} does not exist: run the command results/index.toml gives for "
                          "its folder, or pass --results with a checkout's results/ folder")
    try:
        text = file.read_text()
        if file.suffix == ".jsonl":
            return [json.loads(line) for line in text.splitlines() if line.strip()]
        return json.loads(text)
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ClaimsError(f"cannot read {file}: {exc}; rerun its folder's command") from exc


def load(path: str) -> object:
    """A JSON (or JSON lines, as a list) file under the results folder, read once."""
    return read_path(root() / path)


@cache
def _record(kind: type[R], folder: Path) -> R:
    return kind.read(folder)


def record(kind: type[R], folder: str) -> R:
    """The typed record of the results folder `folder`, read once."""
    return _record(kind, root() / folder)


def record_type(folder: str) -> type[Record] | None:
    """The record type of `folder`'s run: its experiment's `Results`, the experiment named by
    its manifest; None where no manifest names an experiment that declares one."""
    manifest = root() / folder / MANIFEST
    if not manifest.is_file():
        return None
    command = str(read_path(manifest).get("command", "")).split()  # type: ignore[union-attr]
    if command[:1] != ["experiment"] or len(command) < 2 or command[1] not in RECORDS:
        return None
    return RECORDS[command[1]]


def record_of(folder: str) -> Record:
    """The typed record of `folder`, of the type its run's experiment declares."""
    kind = record_type(folder)
    if kind is None:
        raise ClaimsError(f"results/{folder}: its manifest names no experiment with a record")
    return record(kind, folder)


def runs_of(pattern: str) -> list[Path]:
    """The run folders under the results folder that `pattern` (a glob) matches, in order."""
    folders = sorted(f.parent for f in root().glob(f"{pattern}/results.json"))
    if not folders:
        raise ClaimsError(f"no results/{pattern}/results.json: run the command "
                          "results/index.toml gives")
    return folders


def parse(expression: str) -> tuple[str, list[str]]:
    """`name(arg, arg, ...)` with bare-word arguments (no quotes needed): the name and the
    arguments; ("", []) when it is not such an expression."""
    match = re.fullmatch(r"\s*(\w+)\((.*)\)\s*", expression, re.S)
    if not match:
        return "", []
    return match[1], [a.strip() for a in match[2].split(",")] if match[2].strip() else []


def call(expression: str) -> object:
    """Evaluate a source expression (`parse`) on the results folder being read."""
    name, args = parse(expression)
    if name not in SOURCES:
        raise ClaimsError(f"not a results source: {expression!r} (one of "
                          f"{sorted(SOURCES)})")
    try:
        return SOURCES[name](*args)
    except (KeyError, IndexError) as exc:
        raise ClaimsError(f"{expression}: the results hold no {exc}") from exc
    except (TypeError, OSError) as exc:     # arguments it does not take, a file it cannot read
        raise ClaimsError(f"{expression}: {exc}") from exc


def ms(values: list[float], fmt: str) -> str:
    """`mean ± population std` of `values` (`core.stats.mean_std`), empty when there are
    none."""
    return stat(mean_std(values), fmt)


def stat(d: dict | None, fmt: str, scale: float = 1.0) -> str:
    """A `{mean, std}` object as `mean ± std`, empty where there is none (no run to average)."""
    if not d or d.get("mean") is None:
        return ""
    return f"{d['mean'] * scale:{fmt}} ± {d['std'] * scale:{fmt}}"


# How runs are evidence -----------------------------------------------------------------------

def design(folders: list[str], seeds: list[str]) -> tuple[Design, dict[str, str]]:
    """What the seeds of `folders`' runs are as evidence, by the rule the claims judge by
    (`Design`): the folders' units as `results/index.toml` declares them (a folder may be
    scored otherwise than its experiment's default: cross-validated folds, test instances) or,
    where it declares none, as the runs' own records say (their `design_of`, or their `UNIT`);
    with it, each seed's key, where `Design.apply` finds its unit."""
    from macrostate_mj.app.results.provenance import read_index

    where, each = ", ".join(folders), {s: s for s in seeds}
    index = read_index(root())
    entries = [{k: v for k, v in index.get(f.split("/")[0], {}).items() if k in Design.KEYS}
               for f in folders]
    if any(entries):                    # declared beside the results
        if any(e != entries[0] for e in entries):
            raise ValueError(f"{where}: runs of different units cannot pool")
        return Design.of(entries[0], "results/" + folders[0]), each
    kinds = {record_type(f) for f in folders}
    if len(kinds) > 1:
        raise ValueError(f"{where}: runs of different experiments (or of none) cannot pool")
    kind = kinds.pop()
    if kind is None:                    # files no experiment's run wrote: each seed a unit
        if any(_keeps_folds(f) for f in folders):
            raise ClaimsError(f"{where}: cross-validated runs whose manifest names no "
                              "experiment: their folds cannot be read; declare the unit in "
                              "results/index.toml")
        return Design("seed"), each
    if hasattr(kind, "design_of"):
        return kind.design_of([record(kind, f) for f in folders], seeds, where)
    return Design(kind.UNIT), each


def _keeps_folds(folder: str) -> bool:
    """Does `folder`'s results.json say its seeds ran on folds (a profile with `folds`)?"""
    file = root() / folder / "results.json"
    profile = read_path(file).get("profile") if file.is_file() else None  # type: ignore[union-attr]
    return isinstance(profile, dict) and bool(profile.get("folds"))


def paired_of(differences: dict[str, float], folders: list[str], fmt: str = ".2f",
              unit: str = "") -> Paired:
    """Per-seed differences of `folders`' runs over their units (`design`)."""
    plan, keys = design(folders, list(differences))
    return Paired.of(differences, plan, keys, ", ".join(folders), fmt, unit)


# Generic sources: a file and a key path --------------------------------------------------------

@source
def json_value(path: str, keypath: str, fmt: str = ".2f", unit: str = "", scale: str = "1") -> Q:
    """One number of a JSON results file (times `scale`, e.g. 100 for a metre value in cm)."""
    return Q(float(dig(load(path), keypath)) * float(scale), None, fmt, unit)


SOURCES.register("json")(json_value)


@source
def meanstd(path: str, keypath: str, fmt: str = ".3f", unit: str = "", scale: str = "1",
            n: str = "") -> Figure:
    """A `{mean, std, n}` object of a results file (`n` given where the file omits it; a page
    may show one without, a claim refuses it: n 0)."""
    d = dict(dig(load(path), keypath))  # type: ignore[call-overload]
    count = int(n) if n else int(d.get("n", 0))
    return Figure(float(d["mean"]) * float(scale), float(d["std"]) * float(scale), count,
                  None, None, fmt, unit)


@source
def above(path: str, keypath: str, base: str, base_keypath: str, fmt: str = ".1f") -> Q:
    """How much (%) one `{mean, std}` figure's mean lies above another's (negative: below)."""
    a, b = (float(dig(load(f), k)["mean"])  # type: ignore[index]
            for f, k in ((path, keypath), (base, base_keypath)))
    return Q(100 * (a / b - 1), None, fmt, "%")


@source
def paired(path: str, keypath: str, base_keypath: str, fmt: str = ".2f", unit: str = "") -> Paired:
    """Two per-seed lists (or {seed: value} maps, paired by seed) of one results file: the
    mean of their differences (the first minus the second) and its 95 % t interval over the
    folder's independent units (`design`). `path` may join several runs' files with `+`
    (other seeds of the same folds): their {seed: value} maps pool, a seed named twice
    refused, and seeds that share a fold are averaged to it."""
    runs = [load(p) for p in path.split("+")]
    a, b = (dig(runs[0], k) for k in (keypath, base_keypath))
    for run in runs[1:]:
        more = [dig(run, k) for k in (keypath, base_keypath)]
        if any(set(m) & set(have) for m, have in zip(more, (a, b), strict=True)):  # type: ignore[arg-type]
            raise ValueError(f"{path}: a seed appears in more than one run")
        a, b = {**a, **more[0]}, {**b, **more[1]}  # type: ignore[dict-item]
    if not isinstance(a, dict):
        a, b = dict(enumerate(a)), dict(enumerate(b))  # type: ignore[arg-type]
    folders = [str(Path(p).parent) for p in path.split("+")]
    return paired_of({str(s): a[s] - b[s] for s in sorted(a, key=str)},  # type: ignore[index]
                     folders, fmt, unit)


@source
def count(path: str, keypath: str, value: str) -> Q:
    """How many entries of a list or {key: value} map in a results file equal `value` (e.g.
    the folds that chose one range candidate)."""
    entries = dig(load(path), keypath)
    values = entries.values() if isinstance(entries, dict) else entries
    return Q(sum(str(v) == value for v in values), None, "d")  # type: ignore[union-attr]


@source
def quantile(path: str, keypath: str, q: str, fmt: str = ".1f", unit: str = "") -> Q:
    """A quantile of a list of numbers in a results file."""
    values = sorted(float(v) for v in dig(load(path), keypath))  # type: ignore[union-attr]
    return Q(statistics.quantiles(values, n=1000, method="inclusive")[round(float(q) * 1000) - 1]
             if float(q) < 1 else values[-1], None, fmt, unit)


@source
def runs(pattern: str, keypath: str, fmt: str = ".1f", unit: str = "", scale: str = "1") -> Figure:
    """One number of each run folder matching `pattern` (a glob under results/, one run a seed)."""
    files = sorted(root().glob(pattern))
    if not files:
        raise ClaimsError(f"no results/{pattern}: run the command results/index.toml gives")
    return Figure.of({f.parent.name: float(dig(read_path(f), keypath)) * float(scale)
                      for f in files}, fmt, unit)


@source
def ratio(numerator: str, denominator: str, scale: str = "100", offset: str = "-100") -> Figure:
    """scale × a / b + offset per shared unit of two `runs` sources written `pattern|keypath`."""
    a, b = (runs(*side.split("|")) for side in (numerator, denominator))
    assert a.values is not None and b.values is not None
    return Figure.of({k: float(scale) * a.values[k] / b.values[k] + float(offset)
                      for k in a.values if k in b.values}, ".0f", "%")


@source
def share(path: str, keypath: str) -> Figure:
    """A `{share, lo, hi, samples}` object (%): a folder's own bootstrap interval over samples."""
    d = dig(load(path), keypath)
    return Figure(100 * float(d["share"]), 0.0, int(d["samples"]), None,  # type: ignore[index]
                  (100 * float(d["lo"]), 100 * float(d["hi"])), ".1f", "%")  # type: ignore[index]
