"""The experiments that reproduce the dissertation's figures, as one registry.

Each module here is one experiment and exports:

- `Config`: a frozen dataclass of everything its results depend on (a seed included);
- `PROFILES`: named configs, at least `full` (the dissertation's sizes) and `quick` (a smoke run
  the test suite can afford);
- `PRODUCTS`: the files it writes into its output folder (a finished run refuses to be
  overwritten without `--overwrite`);
- `run(config, out, progress) -> list[str]`: writes the products, returns summary lines, and
  registers its module in `EXPERIMENTS` (`@register`) under the module's name (`retlo_sim` ->
  `retlo-sim`);
- `Results`: its record (`core.records.Record`), what its `results.json` holds and its unit,
  which `run` writes through and its sources (`@source`, `app.results.sources`) read through
  (`all`, whose products are the other experiments' folders and an index, has none).

Its command, `experiment NAME`, is generated from the module (`app.cli.experiments`): the
docstring is its help (its first sentence, after "`experiment NAME`:", is its row of the docs'
experiments table), each `Config` field declared with `params.flag` a flag; optionally
`PARALLEL` (its tasks spread over `--workers` and Ray), `FLAGS` and `configure(config,
changes, ...)` (flags that are not one field: the profile's config, the fields' changes and
these flags' values give more changes), `validate(config)` (input checked before the folder
is claimed), `missing(config)` (what `experiment all` skips it for) and the tag `REAL_DATA`
(the published datasets it reads).

`execute` wraps `run` in the one run lifecycle (`core.run.Run`: the folder claimed, the manifest
with the config, its hash, stage timings, its record's type and unit, and how the run ended).
Adding an experiment is one new module (or package) here and its test: `EXPERIMENTS` scans this
package (every module not starting with `_`, imported on first read: `core.registry.scan`), the
CLI lists the names of the modules it scans without importing them (`names`), and its command,
its row of the parameter tests and of the docs' experiments table are generated from it
(docs/explanation/design.md walks one through).
"""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field, fields, is_dataclass, replace
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING, Any

from macrostate_mj.core.cache import TaskCache
from macrostate_mj.core.errors import UserError
from macrostate_mj.core.registry import Registry
from macrostate_mj.core.run import Run

if TYPE_CHECKING:
    from macrostate_mj.core.evidence import Table

CACHE = "cache"          # an experiment's cached tasks, inside its output folder


@dataclass(frozen=True)
class Parallel:
    """An experiment whose tasks spread over local workers (`--workers`, said what one runs)
    and, with `ray`, over a Ray cluster (`--ray`); the results never depend on either."""

    workers: str
    ray: bool = True


@dataclass
class Progress:
    """What an experiment's `run` reports to: stage timings into the manifest, bars on the
    terminal, the task cache of its folder, and where its tasks run."""

    run: Run
    report: Callable[..., None] = lambda stage, done, total=1.0, cached=0.0: None
    workers: int = 1
    ray: str | None = None
    overwrite: bool = False     # the command's --overwrite (`experiment all` passes it on)
    cache: TaskCache = field(init=False)

    def __post_init__(self) -> None:
        self.cache = TaskCache(self.run.out / CACHE)

    @contextlib.contextmanager
    def stage(self, name: str) -> Iterator[None]:
        with self.run.stage(name):
            yield

    def record(self, **extra: Any) -> None:
        self.run.record(**extra)


EXPERIMENTS: Registry[ModuleType] = Registry("experiment", packages=[__name__])


def register(run: Callable[..., list[str]]) -> Callable[..., list[str]]:
    """Decorates an experiment's `run`: registers its module (`Config`, `PROFILES`,
    `PRODUCTS`, `run`) under the module's name, `_` read as `-`, and its record (`Results`,
    declared above `run`) under the same name, for the sources that read its folders."""
    from macrostate_mj.app.results.sources import RECORDS

    module = sys.modules[run.__module__]
    name = _command_name(module.__name__)
    EXPERIMENTS.register(name)(module)
    if (record := getattr(module, "Results", None)) is not None:
        RECORDS.register(name)(record)
    return run


def _command_name(module: str) -> str:
    return module.rsplit(".", 1)[-1].replace("_", "-")


def names() -> list[str]:
    """Every experiment's command name, without importing any (the CLI lists them while
    parsing): the names `register` gives the modules `EXPERIMENTS` scans."""
    return [_command_name(m) for m in EXPERIMENTS.module_names()]


def registry() -> dict[str, ModuleType]:
    """Every experiment module by its command name, in the order of `names` (a module that
    does not register is refused by name here)."""
    return {name: EXPERIMENTS[name] for name in names()}


def experiment(name: str) -> ModuleType:
    return EXPERIMENTS[name]


def profile(name: str, chosen: str) -> Any:
    profiles = experiment(name).PROFILES
    if chosen not in profiles:
        raise UserError(f"experiment {name} has no profile {chosen!r}; choose from "
                        f"{', '.join(profiles)}")
    return profiles[chosen]


def at_precision(config: Any, name: str) -> Any:
    """`config` with every `precision` field in it, nested configs included, set to `name`
    (`estimators.precision`); a config with none (nothing it trains can change it) as it is."""
    changes = {}
    for f in fields(config):
        value = getattr(config, f.name)
        if f.name == "precision":
            changes[f.name] = name
        elif is_dataclass(value) and not isinstance(value, type):
            if (nested := at_precision(value, name)) is not value:
                changes[f.name] = nested
    return replace(config, **changes) if changes else config


def execute(name: str, config: Any, out: Path, overwrite: bool = False, workers: int = 1,
            ray: str | None = None, report: Callable[..., None] | None = None) -> list[str]:
    """Run experiment `name` with `config` into `out` under the run lifecycle."""
    module = experiment(name)
    with Run(out, f"experiment {name}", config, getattr(config, "seed", None), module.PRODUCTS,
             overwrite) as run:
        progress = Progress(run, report or Progress.report, workers, ray, overwrite)
        lines = module.run(config, Path(out), progress)
        run.record(products=module.PRODUCTS, workers=workers, ray=ray)
        if (record := getattr(module, "Results", None)) is not None:
            run.record(results=record.described())      # its type, version and unit
    return lines


def catalogue(results: Path) -> Table:
    """Every registered experiment, generated from its module: what it reproduces (its help),
    its profiles, what its record counts as independent, the published datasets it reads (its
    `REAL_DATA` tag: what `data fetch` takes), and the results folders made by it (their
    commands in results/index.toml)."""
    from macrostate_mj.app.results.provenance import read_index
    from macrostate_mj.core.datasets import DATASETS
    from macrostate_mj.core.evidence import ClaimsError, Code

    index = read_index(results)
    rows: Table = [["experiment", "reproduces", "profiles", "unit", "real data",
                    "results folders"]]
    named = {d for module in registry().values() for d in getattr(module, "REAL_DATA", ())}
    unknown = named - set(DATASETS)
    if unknown:
        raise ClaimsError(f"REAL_DATA names no published dataset: {sorted(unknown)}")
    for name, module in registry().items():
        doc = " ".join((module.__doc__ or "").split("\n\n")[0].split(":", 1)[-1].split())
        record = getattr(module, "Results", None)
        made = [f for f, e in index.items()
                if f"experiment {name} " in e["command"] + " "]
        data = ", ".join(getattr(module, "REAL_DATA", ())) or "-"
        rows.append([Code(name), doc.split(". ")[0].rstrip("."), ", ".join(module.PROFILES),
                     record.UNIT if record else "-", data, ", ".join(made) or "-"])
    return rows
