"""`experiment all`: every experiment of the registry in one command with one profile (`full`
or `quick`), each in its own sub-folder; it resumes after an interruption and writes index.json.

Each experiment of the registry runs with the same profile (`full` or `quick`) under its own
run lifecycle in `<out>/<name>/`, with its own task cache there, on the command's workers or
Ray cluster. A rerun after a kill skips what finished (a finished run of the same config is
kept as it is) and resumes the one that was cut short from its cached tasks. An experiment
whose input data is absent (the dissertation's real data is never part of the project: see
`core.paths.reference_data`) is skipped and said so; one that fails is recorded and the others
still run. `index.json` lists what each produced, its status, config hash and wall time.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from pathlib import Path

from estimators.precision import precision_named
from macrostate_mj.app.experiments import (
    Parallel,
    Progress,
    at_precision,
    execute,
    names,
    register,
    registry,
)
from macrostate_mj.app.params import Choice, Precision, flag
from macrostate_mj.app.results.sources import (
    load,
    root,
    source,
)
from macrostate_mj.core.errors import RunFailure, UserError
from macrostate_mj.core.evidence import Table
from macrostate_mj.core.io import write_json_atomic
from macrostate_mj.core.run import MANIFEST, config_hash, run_finished

INDEX = "index.json"
MEMBERS = tuple(name for name in names() if name != "all")     # listed without imports
PRODUCTS = [INDEX, *MEMBERS]                                   # the index, a folder each


def _members() -> dict:
    """The experiments `all` runs: every one but those that look at a sealed test (`SEALED`:
    a look is counted, so it is never the side effect of another command)."""
    return {name: module for name, module in registry().items()
            if name in MEMBERS and not getattr(module, "SEALED", False)}


@dataclass(frozen=True)
class Config:
    """Which profile every experiment runs with, and optionally which experiments."""

    profile: str = "full"
    # empty: every experiment
    only: tuple[str, ...] = field(default=(), metadata=flag(Choice(
        None, "Run only this experiment (repeatable).", MEMBERS, "--only"),
        shown="every experiment"))
    # every training's arithmetic, where it can be chosen
    precision: str = field(default="fp32", metadata=flag(Precision()))

    def __post_init__(self) -> None:
        precision_named(self.precision)
        unknown = sorted(set(self.only) - set(MEMBERS))
        if unknown:
            raise UserError(f"only names {', '.join(unknown)}, not an experiment; choose from "
                            f"{', '.join(MEMBERS)}", "only")


PROFILES = {"full": Config("full"), "quick": Config("quick")}
PARALLEL = Parallel("every experiment's tasks")


def validate(config: Config) -> None:
    """Refuse, before the folder is claimed, an experiment `all` never runs."""
    sealed = [n for n in config.only if n not in _members()]
    if sealed:
        raise UserError(f"experiment {sealed[0]} scores a sealed test, each look counted: run "
                        "it on its own, not through `experiment all`")


@register
def run(config: Config, out: Path, progress: Progress) -> list[str]:
    """Run (or keep, or skip) every chosen experiment; write the index; summary lines."""
    validate(config)                    # from Python too, not only the command's parse
    chosen = {n: m for n, m in _members().items() if not config.only or n in config.only}
    index: dict = {"profile": config.profile, "experiments": {}}
    failed = []
    for n, (name, module) in enumerate(chosen.items()):
        progress.report("experiments", n, len(chosen))
        sub = at_precision(module.PROFILES[config.profile], config.precision)
        folder = out / name
        entry: dict = {"folder": name, "config_hash": config_hash(sub)}
        absent = getattr(module, "missing", lambda _: None)(sub)
        t0 = time.perf_counter()
        if absent is not None:
            entry |= {"status": "skipped", "reason": f"needs {absent}"}
        elif run_finished(folder, sub):
            entry |= {"status": "kept", "reason": "finished before with this config"}
        else:
            try:
                with progress.stage(name):
                    entry["summary"] = execute(name, sub, folder, progress.overwrite,
                                               progress.workers, progress.ray, progress.report)
                entry["status"] = "finished"
            except (RunFailure, UserError) as err:
                entry |= {"status": "failed", "reason": " ".join(str(err).split())[:300]}
                failed.append(name)
        entry["wall_s"] = round(time.perf_counter() - t0, 1)
        entry["products"] = sorted(p for p in module.PRODUCTS if (folder / p).exists())
        if (folder / MANIFEST).exists():
            entry["manifest"] = f"{name}/{MANIFEST}"
        index["experiments"][name] = entry
        write_json_atomic(out / INDEX, index)       # after each: a kill keeps the index so far
    progress.report("experiments", len(chosen), len(chosen))
    progress.record(experiments={n: e["status"] for n, e in index["experiments"].items()})
    lines = [f"{n:<10} {e['status']:<9} {e['wall_s']:>8.0f} s  {e.get('reason', '')}".rstrip()
             for n, e in index["experiments"].items()]
    if failed:
        raise RunFailure(f"experiment all: {', '.join(failed)} failed (see {out / INDEX}); the "
                         "others are kept, and a rerun resumes the failed ones")
    return [*lines, f"index: {out / INDEX}"]


# Its tables and numbers as the docs show them ----------------------------------------

@source
def all_index(folder: str) -> Table:
    """An `experiment all` folder's index: per experiment its status, wall time and stage
    timings (from its manifest)."""
    index = load(f"{folder}/index.json")
    rows = [["experiment", "profile", "status", "wall (min)", "stages (min)"]]
    for name, entry in index["experiments"].items():  # type: ignore[index]
        file = root() / folder / name / MANIFEST
        stages = json.loads(file.read_text()).get("timings_s", {}) if file.is_file() else {}
        rows.append([name, index["profile"], entry["status"],  # type: ignore[index]
                     f"{entry['wall_s'] / 60:.1f}",
                     ", ".join(f"{k} {v / 60:.1f}" for k, v in stages.items() if k != "total")])
    return rows

