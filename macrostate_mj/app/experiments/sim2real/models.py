"""`experiment sim2real`'s models: one cached training task per arm, seed and share, the
seed-to-fold and share conventions, and the settings each fold's validation block chooses."""

from __future__ import annotations

import json
import tempfile
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from macrostate_mj.app.experiments import Progress
from macrostate_mj.app.experiments.sim2real.config import FINETUNED, MIXING, TUNED, Config
from macrostate_mj.core.cache import Outcome, ShipsFiles, run_tasks, task_key
from macrostate_mj.core.errors import RunFailure
from macrostate_mj.core.stats import mean_std
from macrostate_mj.formats.thymioloc import DEFAULT_PX_PER_CM

Data = Path | np.ndarray


class ModelTask(ShipsFiles):
    """One model of one arm: trained on `train` (fine-tuned from the sim checkpoint `init`, or
    with the sim data `mix` weighing `mix_weight` of the loss), selected on `val`, tested on
    the real block `test`. Keyed by its training settings and the bytes of its data; a sim
    model also outputs its checkpoint (`model.pt`)."""

    stage: ClassVar[str] = "sim2real-model"
    version: ClassVar[int] = 1
    shipped: ClassVar[tuple[str, ...]] = ("train", "val", "mix", "init")   # lab CSVs, checkpoint

    def __init__(self, arm: str, seed: int, epochs: int, train: Data, val: Data,
                 test: np.ndarray, lr: float | None = None, init: Path | None = None,
                 mix: Data | None = None, mix_weight: float = 0.5, chained: bool = True,
                 precision: str = "fp32", select: np.ndarray | None = None,
                 frozen: bool = False, per_instance: bool = False):
        self.arm, self.seed, self.epochs, self.lr, self.chained = arm, seed, epochs, lr, chained
        self.precision = precision
        self.train, self.val, self.test, self.init = train, val, test, init
        self.select = select            # real data it is also scored on, to choose among labs
        self.mix, self.mix_weight = mix, mix_weight
        self.frozen = frozen            # the init's encoders kept fixed
        self.per_instance = per_instance    # the Head's error on each test instance too
        self._key: str | None = None

    def train_config(self) -> Any:
        from estimators.retlo.models import ModelConfig
        from estimators.retlo.train import ENCODER, TrainConfig

        cfg = TrainConfig(epochs=self.epochs, seed=self.seed, chained=self.chained,
                          model=ModelConfig(kind="lstm"), precision=self.precision,
                          frozen=ENCODER if self.frozen else ())
        return cfg if self.lr is None else replace(cfg, lr=self.lr)

    def key(self) -> str:
        if self._key is None:
            inputs = [self.train, self.val, self.test, *([self.init] if self.init else []),
                      *([self.mix] if self.mix is not None else []),
                      *([self.select] if self.select is not None else [])]
            config = {"arm": self.arm, "train": self.train_config()}
            if self.mix is not None:        # keys of the other arms stay as they were
                config["mix_weight"] = self.mix_weight
            if self.per_instance:
                config["per_instance"] = True
            self._key = task_key(self.stage, self.version, config, inputs)
        return self._key

    def compute(self) -> dict[str, bytes]:
        from estimators.retlo.api import evaluate, fit
        from estimators.retlo.models import TorchPredictor
        from estimators.retlo.train import load_checkpoint, save_checkpoint

        cfg = self.train_config()
        init = None if self.init is None else load_checkpoint(self.init)[0]
        mix = [] if self.mix is None else [self.mix]
        net, info = fit([self.train], self.val, cfg, init=init, mix=mix,
                        mix_weight=self.mix_weight)
        report = evaluate(TorchPredictor(net), self.test)
        scores = {"head_cm": report["per_robot_cm"]["H"], "mean_cm": report["mean_error_cm"],
                  "best_val_cm": info["best_val_cm"], "epochs_run": info["epochs_run"]}
        if self.per_instance:       # what a bootstrap over test instances resamples
            scores["head_cm_by_instance"] = [
                evaluate(TorchPredictor(net), self.test[i:i + 1])["per_robot_cm"]["H"]
                for i in range(len(self.test))]
        if self.select is not None:
            scores["select_head_cm"] = evaluate(TorchPredictor(net),
                                                self.select)["per_robot_cm"]["H"]
        files = {"report.json": json.dumps(scores).encode()}
        if self.arm == "sim":            # fine-tuning starts from it
            with tempfile.TemporaryDirectory() as tmp:
                path = save_checkpoint(Path(tmp) / "model.pt", net, DEFAULT_PX_PER_CM, cfg,
                                       info)
                files["model.pt"] = path.read_bytes()
        return files


def sim_task(config: Config, seed: int, lab: Path, val: np.ndarray, test: np.ndarray,
              choose: bool) -> ModelTask:
    """A sim-only model: trained on the lab's Train.csv, its checkpoint picked on the lab's
    Val.csv or on the fold's real validation block (`sim_select`); scored on `val` too where
    it is one of several candidates (`choose`)."""
    picked_on = val if config.sim_select == "real" else lab / "Val.csv"
    return ModelTask("sim", seed, config.epochs, lab / "Train.csv", picked_on, test,
                     chained=config.chained, precision=config.precision,
                     select=val if choose else None)


def candidates(config: Config, arm: str) -> list[dict[str, Any]]:
    """The settings a real-data arm trains one model each of (`TUNED` that reach it, every
    combination of their candidates); [{}] for an arm none reaches."""
    combos: list[dict[str, Any]] = [{}]
    for tuned in (t for t in TUNED if arm in t.arms):
        combos = [{**c, tuned.name: v} for c in combos for v in getattr(config, tuned.name)]
    return combos


def arm_task(arm: str, config: Config, seed: int, train: np.ndarray, val: np.ndarray,
              test: np.ndarray, checkpoint: Path | None, sim: Path | None,
              mix_weight: float | None = None, finetune_epochs: int | None = None
              ) -> ModelTask:
    """The model of a real-data arm: real only, fine-tuned from the seed's sim `checkpoint`
    for `finetune_epochs` (the first of the config's where not given; with its encoders fixed
    in the frozen arm), mixed with the lab Train.csv in `sim` (which weighs `mix_weight` of its
    loss), or both."""
    how = {"chained": config.chained, "precision": config.precision}
    if arm == "real":
        return ModelTask(arm, seed, config.epochs, train, val, test, **how)
    mix = {"mix": sim / "Train.csv", "mix_weight": mix_weight} if arm in MIXING else {}
    if arm in FINETUNED:
        return ModelTask(arm, seed, finetune_epochs or config.finetune_epochs[0], train, val,
                         test, config.finetune_lr, checkpoint, **mix, **how,
                         frozen=arm == "finetune-frozen")
    return ModelTask(arm, seed, config.epochs, train, val, test, **mix, **how)


def fold_of(i: int, folds: int) -> int:
    """The fold model i (seed `seed + i`) is tested on: seeds i and i + folds share one, so
    the folds, not the seeds, are the independent units (docs' intervals average to them)."""
    return i % folds


def share(n: int, fraction: float, i: int) -> slice:
    """Model i's `fraction` of a pool of `n` instances: contiguous part i mod the parts it
    holds, spread evenly from the first instance to the last (a quarter: the four quarters in
    turn), so seeds see different real data rather than one first part each."""
    count = max(1, int(np.ceil(fraction * n)))
    parts = max(1, round(n / count))
    start = int(np.linspace(0, n - count, parts).round()[i % parts])
    return slice(start, start + count)


def best_by(rows: list[dict], key: Callable[[dict], tuple], score: str) -> dict[tuple, dict]:
    """Per `key`, the row of lowest `score` (the first of equals): how both the ranges and the
    mixed arm's share are chosen on the real validation block."""
    best: dict[tuple, dict] = {}
    for r in rows:
        kept = best.get(key(r))
        if kept is None or r[score] < kept[score]:
            best[key(r)] = r
    return best


def choose_settings(reports: list[dict], config: Config) -> tuple[list[dict], dict]:
    """The reports with one model per real-data arm, seed and share: of its candidate settings
    (`TUNED`), the one best on the real validation block that stopped its training
    (`best_val_cm`; the first of equals; the test block takes no part). Per setting named
    several times, also per arm and share the candidate each seed kept and every candidate's
    errors (the `Tuned.table`s; a candidate's model per seed is its best over the other
    settings' candidates)."""
    def key(r: dict) -> tuple:
        return r["arm"], r["seed"], r["fraction"]

    best = best_by(reports, key, "best_val_cm")
    chosen = [r for r in reports if best[key(r)] is r]
    tables: dict[str, dict] = {}
    for tuned in (t for t in TUNED if len(getattr(config, t.name)) > 1):
        for arm in (a for a in tuned.arms if a in config.arms):
            for f in config.fractions:
                cells = {v: list(best_by(
                    [r for r in reports if (r["arm"], r["fraction"], r.get(tuned.name)) ==
                     (arm, f, v)], lambda r: (r["seed"],), "best_val_cm").values())
                    for v in getattr(config, tuned.name)}
                tables.setdefault(tuned.table, {}).setdefault(arm, {})[f"{f:g}"] = {
                    "chosen_by_seed": {str(s): r[tuned.name]
                                       for (a, s, g), r in best.items() if (a, g) == (arm, f)},
                    tuned.cells: {f"{v:g}": {
                        "best_val_cm": mean_std([r["best_val_cm"] for r in c]),
                        "head_cm": mean_std([r["head_cm"] for r in c]),
                        "head_cm_by_seed": {str(r["seed"]): r["head_cm"] for r in c}}
                        for v, c in cells.items()}}
    return chosen, tables


def train_models(tasks: list[tuple[dict, ModelTask]], progress: Progress, total: int,
           earlier: dict[int, Outcome] | None = None) -> dict[int, Outcome]:
    """Run the tasks (cached ones are read back); their outcomes by id(task). The bar counts
    the `earlier` outcomes of the same stage too."""
    done: dict[int, Outcome] = dict(earlier or {})
    for outcome in run_tasks(progress.cache, [t for _, t in tasks], progress.workers,
                             progress.ray):
        if outcome.folder is None:
            raise RunFailure(f"a {outcome.task.arm} model failed: {outcome.failure}")
        done[id(outcome.task)] = outcome
        progress.report("models", len(done), total, sum(o.cached for o in done.values()))
    return done


