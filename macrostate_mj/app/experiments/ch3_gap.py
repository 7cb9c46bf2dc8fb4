"""`experiment ch3-gap`: where chapter 3's 5-robot error comes from, in smoke tests: one Passive
dataset and one chapter-3 model per scenario, our training additions switched off one at a time,
and each module's error given true inputs on the test chains' robot triples.

Per scenario (`--scenario`, repeatable: a built-in or a file), the datasets are `experiment
srs`'s Passive collections at a smaller size (a 3-robot training and validation set, a 5-robot
test; collection seeds 0, 500 and 900) and the model is its predictor (unidirectional LSTM,
cos/sin angles, ℓ = 10; `srs.ModelTask`). On the first scenario's data the training variants
(`VARIANTS`) each train one more model: our additions off one at a time (the estimate fed back,
chained Followers, mirrored instances, the estimate's mark, the Tail-frame rotation) and all of
them off (`text_like`). Every model is also scored module by module: on the test's robot triples
(Head, F1, F2, F3, Tail), each 3-robot module given true inputs estimates its Head alone. One
model each, so these are directions, not measurements.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, ClassVar

from estimators.retlo.files import read_world
from macrostate_mj.app.experiments import Parallel, Progress, register, srs
from macrostate_mj.app.params import Count, Scenarios, Seed, flag
from macrostate_mj.app.results.sources import (
    record,
    source,
)
from macrostate_mj.chain.scenarios import ScenarioRef
from macrostate_mj.core.cache import run_tasks
from macrostate_mj.core.evidence import Table
from macrostate_mj.core.records import Record

PRODUCTS = ["results.json"]
# a variant of chapter 3's training: its `TrainConfig` from ours
VARIANTS: dict[str, Callable[[Any], Any]] = {
    "ours": lambda c: c,
    "no_feedback": lambda c: replace(c, feedback=False),
    "no_chained": lambda c: replace(c, chained=False),
    "no_mirror": lambda c: replace(c, mirror=False),
    "no_mark": lambda c: replace(c, model=replace(c.model, mark_estimates=False)),
    "compass_frame": lambda c: replace(c, model=replace(c.model, rotate=False)),
    "text_like": lambda c: replace(c, feedback=False, chained=False, mirror=False,
                                   model=replace(c.model, mark_estimates=False, rotate=False)),
}
# each 3-robot module of a 5-robot chain (file order H, F1, F2, F3, T) and the robots it sees
TRIPLES = {"module0 (F2 from F3,T)": [2, 3, 4], "module1 (F1 from F2,F3)": [1, 2, 3],
           "module2 (H from F1,F2)": [0, 1, 2]}
DATASET_SEEDS = {"train": 0, "val": srs.VAL_SEED, "test": srs.TEST_SEED}   # as `experiment srs`


@dataclass(frozen=True)
class Config:
    scenarios: tuple[ScenarioRef, ...] = field(default=("webots",), metadata=flag(Scenarios(
        "Repeatable; the training variants run on the first.")))
    train: int = 100
    val: int = 50
    test: int = 50
    epochs: int = field(default=60, metadata=flag(Count(None, "Epochs per model.")))
    seed: int = field(default=0, metadata=flag(Seed(0, "Every model's seed.")))


PROFILES = {"full": Config(), "quick": Config(train=12, val=6, test=6, epochs=1)}
PARALLEL = Parallel("collections and trainings")


class VariantTask(srs.ModelTask):
    """`srs.ModelTask` with one training variant, scored on the whole chain and per module."""

    stage: ClassVar[str] = "ch3-gap-model"

    def __init__(self, train: Any, val: Path, test: Path, epochs: int, seed: int, variant: str):
        super().__init__(train, val, test, epochs, seed)
        self.variant = variant

    def train_config(self) -> Any:
        return VARIANTS[self.variant](super().train_config())

    def _report(self, net: Any, info: dict) -> dict[str, bytes]:
        from estimators.retlo.api import evaluate
        from estimators.retlo.models import TorchPredictor

        predictor, world = TorchPredictor(net), read_world(self.test)
        report = evaluate(predictor, world)
        return {"report.json": json.dumps({
            "all_cm": report["mean_error_cm"], "per_robot_cm": report["per_robot_cm"],
            "best_val_cm": info["best_val_cm"], "best_epoch": info["best_epoch"],
            "modules_cm": {name: evaluate(predictor, world[:, :, idx])["per_robot_cm"]["H"]
                           for name, idx in TRIPLES.items()}}).encode()}


def _name(ref: ScenarioRef) -> str:
    return Path(str(getattr(ref, "name", ref))).stem


@dataclass(frozen=True)
class Results(Record):
    """Per scenario and ablation variant, the model's 5-robot, validation and per-module Head
    errors (one dataset and one model each)."""

    UNIT = "dataset"

    scenarios: dict[str, dict]
    variants: dict[str, dict]
    sizes: dict


@register
def run(config: Config, out: Path, progress: Progress) -> list[str]:
    """Collect each scenario's datasets, train every model; results.json and summary lines."""
    data: dict[str, dict[str, Path]] = {}
    with progress.stage("collect"):
        for ref in config.scenarios:
            chapter = srs.Config(train=config.train, val=config.val, test=config.test,
                                 scenario=ref)
            sets = {part: srs.Dataset(out / "data" / _name(ref) / part,
                                      5 if part == "test" else 3, getattr(config, part),
                                      DATASET_SEEDS[part]) for part in DATASET_SEEDS}
            data[_name(ref)] = {part: ds.ensure(chapter, progress.workers, progress.ray)
                                for part, ds in sets.items()}
    first = _name(config.scenarios[0])
    runs = [(name, "ours") for name in data] + [(first, v) for v in VARIANTS if v != "ours"]
    tasks = [VariantTask(read_world(data[name]["train"]), data[name]["val"], data[name]["test"],
                         config.epochs, config.seed, variant) for name, variant in runs]
    reports: dict[int, dict] = {}
    with progress.stage("train"):
        for outcome in run_tasks(progress.cache, tasks, progress.workers, progress.ray):
            i = tasks.index(outcome.task)
            reports[i] = json.loads((outcome.folder / "report.json").read_text())
            progress.report("train", len(reports), len(tasks))
    results = {"scenarios": {name: reports[i] for i, (name, v) in enumerate(runs)
                             if v == "ours"},
               "variants": {v: reports[i] for i, (name, v) in enumerate(runs) if name == first},
               "sizes": {"train": config.train, "val": config.val, "test": config.test}}
    Results.of(results, "experiment ch3-gap").write(out)
    return [f"{what:<16} 5-robot {r['all_cm']:.1f} cm (validation {r['best_val_cm']:.1f} cm)"
            for part in ("scenarios", "variants") for what, r in results[part].items()
            ] + [f"results: {out / 'results.json'}"]


# Its tables and numbers as the docs show them ----------------------------------------

@source
def ch3_gap(folder: str) -> Table:
    """`experiment ch3-gap`: each model's 5-robot error, its validation error, and its Head
    error per 3-robot module given true inputs (cm; one dataset and one model each)."""
    data = record(Results, folder)
    first = next(iter(data.scenarios))
    rows: Table = []
    for part, label in (("scenarios", "scenario"), ("variants", f"training on {first}")):
        for name, r in getattr(data, part).items():
            if part == "variants" and name == "ours":
                continue                    # the first scenario's row already
            rows.append([label, name, f"{r['all_cm']:.1f}", f"{r['best_val_cm']:.1f}",
                         *(f"{v:.1f}" for v in r["modules_cm"].values())])
    modules = list(data.scenarios[first]["modules_cm"])
    return [["", "", "5-robot error", "validation", *modules], *rows]

