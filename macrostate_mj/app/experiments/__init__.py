"""The experiments that reproduce the dissertation's figures, as one registry.

Each module here is one experiment and exports:

- `Config`: a frozen dataclass of everything its results depend on (a seed included);
- `PROFILES`: named configs, at least `full` (the dissertation's sizes) and `quick` (a smoke run
  the test suite can afford);
- `PRODUCTS`: the files it writes into its output folder (a finished run refuses to be
  overwritten without `--overwrite`);
- `run(config, out, progress) -> list[str]`: writes the products, returns summary lines.

`execute` wraps `run` in the one run lifecycle (`core.run.Run`: the folder claimed, the manifest
with the config, its hash, stage timings and how the run ended). Adding an experiment is one
new module here (found by `registry()`) and its test.
"""

from __future__ import annotations

import contextlib
import importlib
import pkgutil
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field, fields, is_dataclass, replace
from pathlib import Path
from types import ModuleType
from typing import Any

from macrostate_mj.core.cache import TaskCache
from macrostate_mj.core.errors import UserError
from macrostate_mj.core.run import Run

CACHE = "cache"          # an experiment's cached tasks, inside its output folder


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


def names() -> list[str]:
    """Every experiment's command name, from its module's (`retlo_sim` -> `retlo-sim`), without
    importing any (the CLI lists them while parsing)."""
    return sorted(info.name.replace("_", "-") for info in pkgutil.iter_modules(__path__)
                  if not info.name.startswith("_"))


def registry() -> dict[str, ModuleType]:
    """Every experiment module of this package by its command name."""
    return {name: importlib.import_module(f"{__name__}.{name.replace('-', '_')}")
            for name in names()}


def experiment(name: str) -> ModuleType:
    found = registry()
    if name not in found:
        raise UserError(f"unknown experiment {name!r}; choose from {', '.join(found)} "
                        "(`macrostate-mj experiment list`)")
    return found[name]


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
    return lines
