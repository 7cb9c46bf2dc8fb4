"""`experiment retlo`: Fig 2.7 (mean ± std per model and team size), Fig 2.8 (step-wise) and a
Fig 2.9-style video from ThymioLoc files.

Every learned model is trained once per seed on the training files, selected on the validation
file, and tested on every test file whatever its team size (the 3-robot module runs along
longer chains without retraining). With `folds` (§2.6.2's cross-validation), the training files
and the validation file are pooled in that order and cut into contiguous blocks: seed i trains
on the other blocks less their last 15 % (which selects its checkpoint) and is tested on block
i mod folds, so no model is scored on an instance it trained or selected on. The 2X heuristic
has no seed. results.json holds only deterministic numbers (timings go to the manifest), so
the same command gives the same file.

This module composes: reading, training and testing are `estimators.retlo.api`'s, the figures
`viz.retlo_figures`'s, the video over the lab camera's view `viz.lab_backdrop`'s.
"""

from __future__ import annotations

import json
import shutil
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from estimators.retlo import MODEL_KINDS
from estimators.retlo.api import evaluate, fit, predict, report
from estimators.retlo.chain import Module, SplitChain, predict_chain
from estimators.retlo.curves import inside_bias, largest_error_share
from estimators.retlo.files import read_world, world_to_pixels
from estimators.retlo.heads import POINT, Head, head_named
from estimators.retlo.heuristic import Heuristic2X
from estimators.retlo.models import ModelConfig, TorchPredictor
from estimators.retlo.train import TrainConfig, checkpoint_bytes, load_checkpoint
from macrostate_mj.app.experiments import Parallel, Progress, register
from macrostate_mj.app.experiments.retlo.record import CV_TEST, Results
from macrostate_mj.app.params import (
    CSV,
    Chained,
    Count,
    Fraction,
    History,
    InputFile,
    Precision,
    PxPerCm,
    Seed,
    Switch,
    Uncertainty,
    flag,
)
from macrostate_mj.core.cache import run_tasks, task_key
from macrostate_mj.core.errors import UserError
from macrostate_mj.core.io import check_writable_dir
from macrostate_mj.core.paths import real_thymioloc
from macrostate_mj.core.stats import cv_blocks, mean_std
from macrostate_mj.env.estimated import HEURISTIC
from macrostate_mj.formats.thymioloc import DEFAULT_PX_PER_CM

REAL_DATA = ("retlo",)   # the published datasets it reads (`data fetch NAME`)
PRODUCTS = ["results.json", "fig2_7.png", "fig2_8.png", "fig2_9.mp4", "models"]
CV_VAL_SHARE = 0.15     # of each fold's training blocks, the last share selects
FIRST = "first_"        # with --split, the first module's model: models/first_<kind>_seed<i>.pt


@dataclass(frozen=True)
class Config:
    """What `experiment retlo` runs (the published 3-robot files by default); an invalid one
    cannot be built, so a bad flag fails before the output folder is touched."""

    train: tuple[str, ...] = field(
        default_factory=lambda: (str(real_thymioloc("Train.csv")),),
        metadata=flag(InputFile(None, "Training ThymioLoc CSV (repeatable).", CSV,
                                flag="--train"),
                      parse=lambda paths: tuple(str(p) for p in paths), type=list[Path],
                      shown="the published Train.csv"))
    val: str = field(default_factory=lambda: str(real_thymioloc("Val.csv")),
                     metadata=flag(InputFile(None, "Validation CSV.", CSV), parse=str,
                                   type=Path, shown="the published Val.csv"))
    test: tuple[str, ...] = field(default=(), metadata=flag(
        InputFile(None, "Test CSV, any team size (repeatable).", CSV, flag="--test"),
        parse=lambda paths: tuple(str(p) for p in paths), type=list[Path]))
    # fraction of each training file held out as a test set
    holdout: float = field(default=0.0, metadata=flag(Fraction(
        None, "Hold out this fraction of each training file as the 3-robot test instead of "
        "cross-validating (--folds 0).")))
    # training seeds per model: seed, seed + 1, ...
    seeds: int = field(default=5, metadata=flag(Count(None, "Training seeds per model "
                                                      "(seed..seed+seeds-1).")))
    epochs: int = field(default=60, metadata=flag(Count(
        None, "Epochs per training (cosine schedule, early stop).")))
    px_per_cm: float = field(default=DEFAULT_PX_PER_CM, metadata=flag(PxPerCm))
    video_instances: int = 3
    model: ModelConfig = ModelConfig()  # its kind is set per run; history, LSTM direction, angles
    seed: int = field(default=0, metadata=flag(Seed(0, "The first training seed.")))
    # seeds of one kind trained together (`estimators.retlo.ensemble`)
    group: int = field(default=1, metadata=flag(Count(
        None, "Seeds of one model trained together, this many at a time (FC: faster on a "
        "CPU, the LSTM little: `bench --only ensemble`).", max=64)))
    folds: int = 5         # cross-validate over train + val in this many blocks (0: none)
    head: Head = POINT     # GAUSSIAN: every learned model predicts a 2-D Gaussian per robot
    # also train on chained Followers (`TrainConfig.chained`)
    chained: bool = field(default=True, metadata=flag(Chained))
    # module 0 by a model trained without them (`chain.SplitChain`)
    split: bool = field(default=False, metadata=flag(Switch(
        False, "Train each model twice, with and without chained Followers, and run the "
        "unchained one as the first module (whose Follower is measured), the chained one after "
        "it (docs).")))
    # the trainings' arithmetic (`estimators.precision`)
    precision: str = field(default="fp32", metadata=flag(Precision()))

    def __post_init__(self) -> None:
        if self.seeds < 1 or self.epochs < 1:
            raise UserError("--seeds and --epochs must be at least 1")
        if not 0.0 <= self.holdout < 0.9:
            raise UserError(f"--holdout must be in [0, 0.9), got {self.holdout}")
        if self.folds == 1 or self.folds < 0:
            raise UserError(f"--folds {self.folds}: cross-validation needs at least 2 blocks")
        if self.folds and self.holdout:
            raise UserError("--folds and --holdout both choose the 3-robot test; pass one")
        if self.head.uncertain and self.group > 1:
            raise UserError("--group trains point models only; drop it with --uncertainty")
        if self.split and not self.chained:
            raise UserError("--split pairs an unchained first module with chained later ones; "
                            "drop --no-chained")
        if not self.test and self.holdout == 0.0 and not self.folds:
            raise UserError("no test set; pass --test CSV, --holdout FRACTION or --folds K")


PROFILES = {"full": Config(), "quick": Config(seeds=1, epochs=1)}
PARALLEL = Parallel("one training each")
# settings that are not one field: the model's inputs, its head, and the folds' default
FLAGS = {
    "folds": Count(None, "Cross-validate (§2.6.2): pool the training and validation files in "
                   "this many contiguous blocks; seed i is tested on block i mod K and trains "
                   "and selects on the rest; 0: no cross-validation; not given: the "
                   "profile's, or 0 with --holdout.", min=0),
    "history": History,
    "unidirectional": Switch(False, "A unidirectional LSTM (chapter 3's predictor, with "
                             "--cos-sin)."),
    "cos_sin": Switch(False, "Angles as cos/sin pairs (chapter 3's predictor).",
                      "--cos-sin/--radians"),
    "uncertainty": Uncertainty,
}


def configure(config: Config, changes: dict, *, profile: str, workers: int, folds: int | None,
              history: int, unidirectional: bool, cos_sin: bool, uncertainty: str) -> dict:
    """The flags that are not one field, as changes to `config`."""
    if folds is None:
        folds = 0 if changes.get("holdout", config.holdout) else config.folds
    return {"folds": folds, "head": head_named(uncertainty),
            "model": ModelConfig(history=history, bidirectional=not unidirectional,
                                 cos_sin=cos_sin)}


def missing(cfg: Config) -> str | None:
    """The input this run cannot start without, if it is absent (`experiment all` skips it)."""
    absent = [p for p in (*cfg.train, cfg.val, *cfg.test) if not Path(p).is_file()]
    return f"the ThymioLoc file {absent[0]}" if absent else None


@register
def run(cfg: Config, out: Path, progress: Progress) -> list[str]:
    """Train, test, plot, draw; return summary lines."""
    from viz.lab_backdrop import write_lab_video
    from viz.retlo_figures import plot_overall, plot_stepwise

    px = cfg.px_per_cm
    with progress.stage("read"):
        folds, shared = _read(cfg)
    models_dir = check_writable_dir(out / "models")
    reports = {t["name"]: {HEURISTIC: [evaluate(Heuristic2X(), t["world"])]} for t in shared}
    if cfg.folds:   # the heuristic on every block: each instance scored once
        reports[CV_TEST] = {HEURISTIC: [evaluate(Heuristic2X(), f.test["world"]) for f in
                                        folds[:cfg.folds]]}
    tests = shared + ([folds[0].test] if cfg.folds else [])
    big = max(tests, key=lambda t: t["world"].shape[2])
    curves: dict[str, list[dict]] = {kind: [] for kind in MODEL_KINDS}
    # per seed and kind the model, then (with --split) its first module's: trained unchained
    tasks = [TrainTask(fold.trains, fold.val, TrainConfig(epochs=cfg.epochs, seed=seed,
                                                          chained=chained,
                                                          model=replace(cfg.model, kind=kind),
                                                          precision=cfg.precision), px,
                       cfg.head)
             for seed, fold in zip(range(cfg.seed, cfg.seed + cfg.seeds), folds, strict=True)
             for kind in MODEL_KINDS
             for chained in ((cfg.chained, False) if cfg.split else (cfg.chained,))]
    folders: dict[int, Path] = {}
    cached = 0
    with progress.stage("train"):
        for outcome in run_tasks(progress.cache, tasks, progress.workers, progress.ray,
                                 cfg.group):
            folders[tasks.index(outcome.task)] = outcome.folder
            cached += outcome.cached
            progress.report("train", len(folders), len(tasks), cached)
    train_s: dict[str, list[float]] = {kind: [] for kind in MODEL_KINDS}
    per_model = 2 if cfg.split else 1
    for i in range(0, len(tasks), per_model):   # in task order: the same file for any workers
        kind, seed = tasks[i].cfg.model.kind, tasks[i].cfg.seed
        train_s[kind].append(sum(json.loads((folders[j] / "timing.json").read_text())["seconds"]
                                 for j in range(i, i + per_model)))
        name = f"{kind}_seed{seed}.pt"
        for j, prefix in zip(range(i, i + per_model), ("", FIRST), strict=False):
            shutil.copyfile(folders[j] / "model.pt", models_dir / f"{prefix}{name}")
        module = _load(models_dir, name, cfg.split)
        own = folds[seed - cfg.seed].test
        for t in shared + ([own] if own else []):   # one prediction per test set: its report,
            est, cov = predict(module, t["world"], gaussian=cfg.head.uncertain)  # and Fig 2.9's
            reports[t["name"]].setdefault(kind, []).append(report(module, t["world"], est, cov))
            if t["name"] == big["name"]:
                curves[kind].append(_fig2_9(est, t["world"]))
    results = {
        "tests": [{"name": t["name"], "n_robots": int(t["world"].shape[2]),
                   "n_instances": int(t["world"].shape[0])} for t in shared]
        + ([{"name": CV_TEST, "n_robots": int(folds[0].test["world"].shape[2]),
             "n_instances": sum(len(f.test["world"]) for f in folds[:cfg.folds]),
             "folds": cfg.folds}] if cfg.folds else []),
        "results": {name: {m: _aggregate(r) for m, r in per.items()}
                    for name, per in reports.items()},
        "seeds": cfg.seeds, "px_per_cm": px,
        "fig2_9": {"test": big["name"], **{kind: _aggregate_curves(per)
                                            for kind, per in curves.items()}},
    }
    Results.of(results, "experiment retlo").write(out)
    with progress.stage("draw"):
        plot_overall(results, out / "fig2_7.png")
        plot_stepwise(results, big["name"], out / "fig2_8.png")
        shown = big["world"][:cfg.video_instances]
        est = predict_chain(_load(models_dir, f"lstm_seed{cfg.seed}.pt", cfg.split), shown)
        write_lab_video(out / "fig2_9.mp4", world_to_pixels(shown, px),
                        world_to_pixels(est, px), px)
    progress.record(video_test=big["name"])
    return _summary(results, train_s)


def _load(models_dir: Path, name: str, split: bool) -> Module:
    """A trained model as the chain runs it; with --split, paired with its first module's."""
    main = TorchPredictor(load_checkpoint(models_dir / name)[0])
    if not split:
        return main
    return SplitChain(TorchPredictor(load_checkpoint(models_dir / f"{FIRST}{name}")[0]), main)


class TrainTask:
    """One learned model (kind, seed) as a cached task, keyed by its training config, the
    px scale and the training and validation chains' bytes."""

    stage: ClassVar[str] = "retlo-model"
    version: ClassVar[int] = 1
    uncertain_version: ClassVar[int] = 2    # an uncertain model's checkpoint (2: region radii)

    def __init__(self, trains: list[np.ndarray], val: np.ndarray, cfg: TrainConfig, px: float,
                 head: Head = POINT):
        self.trains, self.val, self.cfg, self.px, self.head = trains, val, cfg, px, head

    def key(self) -> str:       # a point model's key names no head (the keys it always had)
        return task_key(self.stage, self.version, {"train": self.cfg, "px_per_cm": self.px,
                                                   **({"head": asdict(self.head),
                                                       "head_version": self.uncertain_version}
                                                      if self.head.uncertain else {})},
                        [*self.trains, self.val])

    def compute(self) -> dict[str, bytes]:
        net, info = fit(self.trains, self.val, self.cfg, head=self.head)
        return self._files(net, info)

    def _files(self, net: Any, info: dict) -> dict[str, bytes]:
        return {"model.pt": checkpoint_bytes(net, self.px, self.cfg, info),
                "timing.json": json.dumps({"seconds": info["train_seconds"]}).encode()}

    def group(self) -> tuple:
        """Models of one kind and settings (seeds apart) train together (`--group`)."""
        return (replace(self.cfg, seed=0), self.px)

    @classmethod
    def compute_group(cls, tasks: list[TrainTask]) -> list[dict[str, bytes]]:
        from estimators.retlo.ensemble import Job, train_many

        trained = train_many([Job(t.trains, t.val, t.cfg) for t in tasks])
        return [t._files(net, info) for t, (net, info) in zip(tasks, trained, strict=True)]


@dataclass(frozen=True)
class Fold:
    """What one seed trains on, selects on, and (under --folds) is tested on alone."""

    trains: list[np.ndarray]
    val: np.ndarray
    test: dict | None = None


def _read(cfg: Config) -> tuple[list[Fold], list[dict]]:
    """Per seed its training chains, validation chains and own test (a cross-validation
    block); and the test sets every seed shares: each training file's holdout, then the test
    files."""
    for path in (*cfg.train, cfg.val, *cfg.test):
        if not Path(path).is_file():
            raise UserError(f"no file {path}; run `macrostate-mj data fetch retlo`, pass "
                            "--train/--val/--test, or set MACROSTATE_REFERENCE_DATA to the "
                            "folder holding ReTLo/")
    shared = []
    worlds = [read_world(p, cfg.px_per_cm) for p in (*cfg.train, cfg.val)]
    if cfg.folds:
        if len({w.shape[1:] for w in worlds}) != 1:
            raise UserError("--folds pools --train and --val: they must hold chains of one "
                            "team size and length")
        pooled = np.concatenate(worlds)
        folds = []
        for i in range(cfg.seeds):
            pool, val, test = cv_blocks(len(pooled), cfg.folds, i % cfg.folds, CV_VAL_SHARE)
            folds.append(Fold([pooled[pool]], pooled[val],
                              {"name": CV_TEST, "world": pooled[test]}))
    else:
        trains = []
        for path, world in zip(cfg.train, worlds, strict=False):
            kept, held = holdout_split(world, cfg.holdout)
            trains.append(kept)
            if len(held):
                shared.append({"name": f"holdout of {Path(path).name}", "world": held})
        folds = [Fold(trains, worlds[-1])] * cfg.seeds
    shared += [{"name": Path(p).name, "world": read_world(p, cfg.px_per_cm)} for p in cfg.test]
    return folds, shared


def holdout_split(world: np.ndarray, fraction: float) -> tuple[np.ndarray, np.ndarray]:
    """(kept, held out) instances; a fixed seed so every run holds out the same ones."""
    order = np.random.default_rng(0).permutation(len(world))
    n_out = int(round(fraction * len(world)))
    if fraction and not 0 < n_out < len(world):
        raise UserError(f"--holdout {fraction} leaves no training or no test instance")
    return world[np.sort(order[n_out:])], world[np.sort(order[:n_out])]


def _aggregate(reports: list[dict]) -> dict:
    """Mean ± std over seeds of one model's reports on one test set."""
    robots = list(reports[0]["per_robot_cm"])
    n_steps = len(reports[0]["per_step_cm"])
    return {
        "mean_error_cm": mean_std([r["mean_error_cm"] for r in reports]),
        "per_seed_cm": [r["mean_error_cm"] for r in reports],
        "per_robot_cm": {b: mean_std([r["per_robot_cm"][b] for r in reports]) for b in robots},
        "per_robot_step_cm": {b: [mean_std([r["per_robot_step_cm"][b][i] for r in reports])
                                  for i in range(n_steps)] for b in robots},
        "first_step": reports[0]["first_step"], "step_s": reports[0]["step_s"],
        **({"calibration": {who: {k: mean_std([r["calibration"][who][k] for r in reports])
                                  for k in cal if k != "n"}
                            for who, cal in reports[0]["calibration"].items()
                            if who != "nll_unit"}}
           if "calibration" in reports[0] else {}),
    }


def _fig2_9(est: np.ndarray, world: np.ndarray) -> dict:
    """Fig 2.9's two claims on one model's estimates (`estimators.retlo.curves`)."""
    return {"inside_bias": inside_bias(est, world),
            "largest_error": largest_error_share(est, world)}


def _aggregate_curves(per_seed: list[dict]) -> dict:
    """Mean ± std over seeds of the inside bias (cm) and of each robot's largest-error share."""
    robots = list(per_seed[0]["inside_bias"])
    return {"inside_cm": {r: mean_std([p["inside_bias"][r]["inside_cm"] for p in per_seed])
                          for r in robots},
            "curved_steps": {r: per_seed[0]["inside_bias"][r]["steps"] for r in robots},
            "largest_error_share": {r: mean_std([p["largest_error"][r] for p in per_seed])
                                    for r in per_seed[0]["largest_error"]}}


def _summary(results: dict, train_s: dict[str, list[float]]) -> list[str]:
    lines = []
    for test in results["tests"]:
        res = results["results"][test["name"]]
        parts = [f"{test['name']} ({test['n_robots']} robots, {test['n_instances']} inst.):"]
        for model in (HEURISTIC, *MODEL_KINDS):
            m = res[model]["mean_error_cm"]
            parts.append(f"{model} {m['mean']:.2f} ± {m['std']:.2f} cm")
        gain = 1 - res["lstm"]["mean_error_cm"]["mean"] / res["fc"]["mean_error_cm"]["mean"]
        lines.append("  ".join(parts) + f"  (LSTM {100 * gain:.0f} % below FC)")
    for kind, secs in train_s.items():
        lines.append(f"training {kind}: {np.mean(secs):.0f} s per seed (max {max(secs):.0f} s)")
    return lines
