"""`experiment sim2real`: how far lab data carries a ReTLo model on real data, and how much real
data sim pre-training saves (a data-efficiency curve).

Real data: a folder of ThymioLoc 3-robot files, `Train.csv` then `Val.csv`, pooled in that order
and cut into `folds` contiguous blocks (instances overlap in time, so a random split would leak);
with `train_only`, Train.csv alone, Val.csv left sealed for `experiment s2r-sealed`.
Model i (seed `seed + i`) is tested on block i mod `folds`, never used by any model of that
seed; of the other blocks, the last `val_share` selects the real-trained checkpoints and the rest
is the real training pool, of which 10 / 25 / 50 / 100 % are used (contiguous parts in turn
over the seeds: `share`). Four arms per seed
(`arms` picks some: `sim` alone asks only how far a lab collection carries):
- sim: trained and selected on a lab collection only (`collect --scenario SCENARIO --robots 3
  --split 80/20/0 [--randomize PROFILE]`, a `collect` run in `data/sim`, or `--sim DIR` with
  Train.csv and Val.csv); with `sim_select` "real", trained on it and selected on the fold's
  real validation block;
- real: trained on a fraction of the pool, selected on the real validation block;
- finetune: the same seed's sim model trained further on the same fraction (`finetune_epochs`;
  name several and each seed and fraction keeps the one best on the real validation block);
- mixed: trained on the same fraction and the lab Train.csv together (`mix_weight`; name
  several and each seed and fraction keeps the one best on the real validation block);
- finetune-mixed: the seed's sim model trained further on the same fraction with the lab
  Train.csv mixed in, as the mixed arm mixes it (pre-trained on the lab, then fine-tuned
  without forgetting it);
- finetune-frozen: as finetune, with the sim model's observation and history encoders kept
  fixed (`train retlo --freeze-encoder`): fewer weights for a small real share to move.
Where the lab's factors come from (`fits`, `--fit`): the scenario as written; a `sysid` fit on
the real Train.csv (leaky under these folds, whose test blocks it has seen); or the nested
protocol, one fit per fold on that fold's training and validation blocks alone, so the
cross-validated ratio estimates what a held-out real test will show. Naming several trains
each one's sim-only models on the same folds (`sim_by_fit`). The randomization ranges drawn
around the factors (`randomize`, `--randomize`) can be chosen inside each fold as well: name
several candidates (`none` for no ranges) and each seed's sim model is the candidate's whose
Head error on that fold's real validation block is lowest (`ranges`); the test block never
takes part. What each modelled difference is worth (`ablate`, `--ablate`): per seed, a lab
collected from that seed's own profile with the named parameters switched off (their factor 1,
or their value 0) trains one more sim-only model; its Head error minus the lab's, paired by
seed, averaged to the folds, with a 95 % interval over them (`ablations`).
Every model is the LSTM of `train retlo --model lstm`, a cached task
(`cache/sim2real-model/<key>/`: its report, and a sim model's checkpoint) keyed by its training
settings and the bytes of its data (the lab CSVs, the real blocks, a fine-tuned model's sim
checkpoint): a rerun after a kill trains only what is missing, and new inputs (a refit lab, other
real files) train new models instead of mixing with the old.
"""

from __future__ import annotations

import json
import tempfile
from collections import Counter
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from numbers import Integral
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import typer

from collectors.runner import CollectRequest, collect, finished
from macrostate_mj.app.experiments import Parallel, Progress, register
from macrostate_mj.app.params import (
    MAX_SECONDS,
    REAL_FOLDER,
    Chained,
    Choice,
    InputDir,
    Positive,
    Precision,
    Scenario,
    Seed,
    Switch,
    flag,
)
from macrostate_mj.chain.scenario import ScenarioConfig
from macrostate_mj.chain.scenarios import ScenarioRef, get_scenario
from macrostate_mj.core.cache import Outcome, ShipsFiles, run_tasks, task_key
from macrostate_mj.core.errors import RunFailure, UserError
from macrostate_mj.core.io import write_json_atomic
from macrostate_mj.core.paths import real_thymioloc
from macrostate_mj.core.stats import cv_blocks, cv_ratio, mean_std, paired_interval
from macrostate_mj.formats.thymioloc import DEFAULT_PX_PER_CM, read_csv

PRODUCTS = ["results.json", "sim2real.png"]
ARMS = ("sim", "real", "finetune", "mixed", "finetune-mixed", "finetune-frozen")
MIXING = ("mixed", "finetune-mixed")      # the arms that mix the lab data into the loss
REAL_FILES = ("Train.csv", "Val.csv")
FITS = ("none", "train", "fold")
SIM_SELECT = ("lab", "real")    # what chooses a sim model's checkpoint (`Config.sim_select`)
PLAIN = "none"      # a `randomize` candidate: no ranges (the fitted factors fixed, or the lab)
FINETUNED = ("finetune", "finetune-mixed", "finetune-frozen")   # start from the sim model


@dataclass(frozen=True)
class Tuned:
    """A setting of real-data arms given as candidates (`Config.<name>`): each seed and share
    keeps the arm's model best on the real validation block (`choose_settings`); with several
    candidates, `results.json[table]` gives each one's errors (`cells` per candidate) and the
    summary says how often each was kept (as `label`)."""

    name: str
    arms: tuple[str, ...]
    table: str
    cells: str
    label: str


TUNED = (Tuned("mix_weight", MIXING, "mixes", "weights", "lab share"),
         Tuned("finetune_epochs", FINETUNED, "finetunes", "epochs", "epochs"))


@dataclass(frozen=True)
class Config:
    seeds: int = 5
    folds: int = 5
    fractions: tuple[float, ...] = field(default=(0.1, 0.25, 0.5, 1.0), metadata=flag(Positive(
        None, "Train the real-data arms on this share of the real pool (repeatable).",
        "--fraction", max=1.0), parse=lambda given: tuple(sorted(set(given)))))
    val_share: float = 0.15
    epochs: int = 60
    # the fine-tuned arms' epochs (cosine decay over them); with several, each seed and share
    # keeps the count whose model does best on the real validation block (`finetunes`)
    finetune_epochs: tuple[int, ...] = field(default=(30,), metadata=flag(Positive(
        None, "The fine-tuned arms' epochs on the real data. Repeatable: each seed and share "
        "then keeps the count whose model does best on its real validation block.",
        "--finetune-epochs", max=10_000), parse=lambda given: tuple(sorted(set(given)))))
    finetune_lr: float = 5e-4
    # the mixed arm's lab share of the loss; with several, each seed and share keeps the
    # weight whose model does best on the real validation block that stopped it (`mixes`)
    mix_weight: tuple[float, ...] = field(default=(0.5,), metadata=flag(Positive(
        None, "The mixed arm: the lab data's share of the loss, in (0, 1). Repeatable: each "
        "seed and share then keeps the weight whose model does best on its real validation "
        "block.", "--mix-weight", max=1.0), parse=lambda given: tuple(sorted(set(given)))))
    sim_minutes: float = 100.0
    sim_seed: int = 31
    episode_minutes: float = 5.0
    seed: int = field(default=0, metadata=flag(Seed(0, "The first model seed: model i trains "
                                                    "with seed+i and is tested on real fold i "
                                                    "mod 5.")))
    real: Path = field(default_factory=real_thymioloc, metadata=REAL_FOLDER)
    # the lab the collection is made in
    scenario: ScenarioRef = field(default="lab", metadata=flag(Scenario, default="lab"))
    # a lab collection's folder, instead of collecting one
    sim: Path | None = field(default=None, metadata=flag(InputDir(
        None, "A lab collection folder (Train.csv, Val.csv) to use instead of collecting one "
        "(`collect --scenario lab --robots 3 --split 80/20/0`).")))
    # the lab collection's domain randomization: none, one profile, or candidates (`PLAIN`
    # among them for none) chosen per fold on its real validation block
    randomize: tuple[str, ...] = field(default=(), metadata=flag(typer.Option(
        None, "--randomize", help="A domain-randomization profile or JSON of factors for the "
        "lab collection (e.g. sysid's fitted.json). Repeatable: each fold then picks the "
        "candidate (`none` for no ranges) whose sim model does best on its own real validation "
        "block. The full profile's wider (as the docs' figure) is what `experiment all` "
        "runs."), default=(), shown="none"))
    # which arms to train (a fine-tuned arm trains the sim models)
    arms: tuple[str, ...] = field(default=ARMS[:4], metadata=flag(Choice(
        None, "Train only this arm (repeatable): `--arm sim` asks only how far a lab collection "
        "carries. sim, real, finetune and mixed when none is named.", ARMS, "--arm"),
        parse=lambda given: tuple(a for a in ARMS if a in given)))
    # train on chained Followers too (`TrainConfig.chained`)
    chained: bool = field(default=True, metadata=flag(Chained))
    # cross-validate on Train.csv alone, Val.csv never read: the real Val file stays the sealed
    # test `experiment s2r-sealed` scores once (choose here, then look there)
    train_only: bool = field(default=False, metadata=flag(Switch(
        False, "Cross-validate on the real Train.csv alone, never reading Val.csv: what "
        "chooses a setting before `experiment s2r-sealed` scores it on the sealed Val.csv.",
        "--train-only/--with-val")))
    # what chooses each sim model's checkpoint: the lab's Val.csv (sim data only, the text's
    # protocol), or the fold's real validation block (what a lab with a real file can do; the
    # test block still takes no part)
    sim_select: str = field(default="lab", metadata=flag(Choice(
        None, "What stops each sim model's training and picks its checkpoint: the lab "
        "collection's Val.csv, or the fold's real validation block (the test block takes no "
        "part either way).", SIM_SELECT, "--sim-select")))
    # the trainings' arithmetic (`estimators.precision`)
    precision: str = field(default="fp32", metadata=flag(Precision()))
    # where the lab's factors come from (`FITS`): the scenario as written, a `sysid` fit on the
    # real Train.csv (what a lab with one real file does; under these folds it has seen the
    # test blocks), or one fit per fold on that fold's training blocks only (the nested
    # protocol). The first fit's lab data trains the sim arm and feeds the later arms; each
    # other fit trains a sim-only model of its own, on the same folds (`sim_by_fit`). With a
    # fit, `randomize` names the ranges drawn around the fitted factors.
    fits: tuple[str, ...] = field(default=("none",), metadata=flag(Choice(
        None, "Where the lab's factors come from (repeatable: the first feeds every arm, each "
        "other trains a sim-only model on the same folds): none (the scenario as written), "
        "train (`sysid` on the real Train.csv, which these folds' test blocks are cut from), "
        "fold (one fit per fold on its training blocks only: the nested protocol, what a "
        "held-out test will show). With a fit, --randomize names the ranges drawn around it.",
        FITS, "--fit")))
    sysid_first: int = 16
    sysid_refine: int = 8
    sysid_minutes: float = 30.0
    # groups of lab parameters (`collectors.randomize.PARAMETERS`) switched off in turn, each
    # group's sim-only models paired with the lab's (`ablations`)
    ablate: tuple[tuple[str, ...], ...] = field(default=(), metadata=flag(typer.Option(
        None, "--ablate", help="Switch these lab parameters off (comma-separated, e.g. "
        "frame_hz,frame_jitter; repeatable, one group each): each group trains sim-only models "
        "on a lab collected without them, paired with the lab's own over the folds. Needs "
        "--fit or --randomize."), parse=lambda groups: tuple(
            tuple(n.strip() for n in g.split(",") if n.strip()) for g in groups)))

    @property
    def lab(self) -> ScenarioConfig:
        """The scenario the lab data is collected in, resolved."""
        return get_scenario(self.scenario)

    @property
    def candidates(self) -> tuple[str, ...]:
        """The `randomize` candidates (`PLAIN` alone where none is named)."""
        return self.randomize or (PLAIN,)


PARALLEL = Parallel("collection and trainings")
# not a field's flag: given with --sim, it sizes nothing (`configure` refuses the pair)
FLAGS = {"sim_minutes": Positive(None, "Minutes of lab data to collect.", "--sim-minutes",
                                 max=MAX_SECONDS / 60)}


def configure(config: Config, changes: dict, *, profile: str, workers: int,
              sim_minutes: float | None) -> dict:
    """The command's `--sim-minutes` (refused with `--sim`, whose folder it would not size)."""
    if sim_minutes is None:
        return {}
    if changes.get("sim", config.sim) is not None:
        raise UserError("--sim-minutes sizes the lab collection this command makes; drop it "
                        "or --sim")
    return {"sim_minutes": sim_minutes}


PROFILES = {
    # what `experiment all` runs: every arm on `wider` lab data (the committed
    # results/s2r_mixed); the command's own --randomize replaces it (none by default)
    "full": Config(randomize=("wider",)),
    "quick": Config(seeds=2, fractions=(0.5, 1.0), epochs=2, finetune_epochs=(1,),
                    sim_minutes=6.0, episode_minutes=3.0, sysid_first=2, sysid_refine=1,
                    sysid_minutes=1.0),
}


def missing(config: Config) -> str | None:
    """The input this run cannot start without, if it is absent (`experiment all` skips it)."""
    return None if Path(config.real).is_dir() else \
        f"the real ThymioLoc folder {config.real} (`macrostate-mj data fetch retlo`)"


def _require_splits(folder: Path, flag: str, hint: str, files: tuple[str, ...] = REAL_FILES
                    ) -> None:
    """One-line error unless `folder` holds `files` (Train.csv and Val.csv)."""
    missing = [f for f in files if not (folder / f).is_file()]
    if missing:
        raise UserError(f"{flag} {folder} has no {missing[0]}; pass {hint}")


def read_real(folder: Path, train_only: bool = False) -> np.ndarray:
    """The pooled real instances (px, degrees), Train then Val (Train alone with
    `train_only`: Val.csv is not even opened); one-line errors otherwise."""
    files = REAL_FILES[:1] if train_only else REAL_FILES
    _require_splits(folder, "--real", "the folder of the real ThymioLoc Train.csv and Val.csv "
                    "(`macrostate-mj data fetch retlo` gets them)", files)
    parts = [read_csv(folder / f).poses for f in files]
    if len({p.shape[1:] for p in parts}) != 1 or parts[0].shape[2] != 3:
        raise UserError(f"--real {folder}: Train.csv and Val.csv must both hold 3-robot "
                        "instances of the same length")
    return np.concatenate(parts)


def validate(config: Config) -> np.ndarray:
    """Refuse bad inputs in one line before anything is written; the pooled real instances."""
    from collectors.randomize import PARAMETERS, Randomization

    if config.sim is not None and config.lab != get_scenario("lab"):
        raise UserError("--scenario names the lab this command collects in; drop it or --sim")
    for weight in config.mix_weight:
        if not 0.0 < weight < 1.0:
            raise UserError(f"--mix-weight {weight:g}: the lab data's share of the mixed arm's "
                            "loss must be in (0, 1)")
    for epochs in config.finetune_epochs:
        if isinstance(epochs, bool) or not isinstance(epochs, int) or epochs < 1:
            # a numpy integer is refused too (the results file could not hold it): say so
            kind = f" ({type(epochs).__name__}: pass int(...))" if isinstance(
                epochs, Integral) and not isinstance(epochs, int) else ""
            raise UserError(f"--finetune-epochs {epochs}{kind}: the fine-tuned arms' epochs must "
                            "be whole numbers of at least 1")
    if not config.finetune_epochs:
        raise UserError("--finetune-epochs: name at least one count (30 by default)")
    if config.sim_select not in SIM_SELECT:
        raise UserError(f"--sim-select {config.sim_select}: choose {' or '.join(SIM_SELECT)}")
    pooled = read_real(config.real, config.train_only)
    unknown = [a for a in config.arms if a not in ARMS]
    if unknown or not config.arms:
        raise UserError(f"--arm {', '.join(unknown) or '(none)'}: choose among "
                        f"{', '.join(ARMS)}")
    if config.folds > len(pooled):
        raise UserError(f"--real {config.real} holds {len(pooled)} instances, fewer than "
                        f"{config.folds} folds")
    if config.sim is not None:
        _require_splits(config.sim, "--sim", "a `collect --split` folder")
        if config.randomize:
            raise UserError("--randomize applies to the lab collection this command makes; "
                            "drop it or --sim")
    if len(set(config.randomize)) != len(config.randomize):
        raise UserError(f"--randomize {', '.join(config.randomize)}: name each candidate once")
    for profile in config.randomize:
        if profile != PLAIN:
            Randomization.parse(profile)
    bad = [f for f in config.fits if f not in FITS]
    if bad or not config.fits or len(set(config.fits)) != len(config.fits):
        raise UserError(f"--fit {', '.join(bad or config.fits) or '(none)'}: name each of "
                        f"{', '.join(FITS)} at most once")
    if config.fits != ("none",) and config.sim is not None:
        raise UserError("--fit fits the lab collection this command makes; drop it or --sim")
    if config.ablate and (config.sim is not None or
                          config.fits[0] == "none" and config.candidates == (PLAIN,)):
        raise UserError("--ablate switches off parameters of the lab's profile; make the first "
                        "--fit train or fold, or give --randomize (and no --sim)")
    if config.ablate and config.arms == ("real",):
        raise UserError("--ablate trains sim-only models; add --arm sim")
    groups = [tuple(sorted(g)) for g in config.ablate]
    if len(set(groups)) != len(groups):
        raise UserError("--ablate: name each group once")
    unknown = [n for group in config.ablate for n in group if n not in PARAMETERS]
    if unknown or any(not group for group in config.ablate):
        raise UserError(f"--ablate {', '.join(unknown) or '(empty)'}: name parameters of "
                        f"{', '.join(PARAMETERS)}, comma-separated")
    return pooled


def _collect(config: Config, out: Path, progress: Progress, randomize: str | None) -> Path:
    """A lab collection in `out` (a `collect` run: resumed, and replaced when another config
    made it, its episodes kept)."""
    req = CollectRequest(config.lab, 3, config.sim_minutes, config.sim_seed, out, "passive",
                         workers=progress.workers, ray=progress.ray, split="80/20/0",
                         overwrite=True, episode_minutes=config.episode_minutes,
                         randomize=randomize)
    if not finished(req):
        collect(req, lambda _, minutes, resumed: progress.report(
            f"lab data {out.name}", minutes, config.sim_minutes, resumed))
    return out


def _drawn_lab(config: Config, profile: dict, kind: str, out: Path, progress: Progress
               ) -> Path:
    """A lab collection drawn from `profile`, in `out / "data"` under a folder named by the
    profile (runs and folds that draw the same share it), the profile written beside it."""
    folder = out / "data" / f"{kind}-{task_key('sim2real-lab', 1, profile)[:12]}"
    folder.mkdir(parents=True, exist_ok=True)
    path = folder.parent / f"{folder.name}.profile.json"
    write_json_atomic(path, profile)
    return _collect(config, folder, progress, str(path) if profile else None)


def _ranges(randomize: str) -> dict | None:
    """A `randomize` candidate's ranges (None for `PLAIN`)."""
    from collectors.randomize import Randomization

    return None if randomize == PLAIN else Randomization.parse(randomize).profile()


def _fitted_lab(config: Config, train: np.ndarray, val: np.ndarray, out: Path, name: str,
                progress: Progress) -> tuple[dict[str, Path], dict]:
    """`sysid` on real poses `train` (checked on `val`), then per `randomize` candidate a lab
    collection drawn around the fitted factors (its ranges times each factor) in
    `out / "data"`. The candidates' collections of the fit are cached in `out / "sysid"`,
    shared by every fit of the run."""
    from collectors.randomize import around
    from collectors.sysid import SysidConfig, fit

    cfg = SysidConfig(scenario=config.lab, robots=3, minutes=config.sysid_minutes,
                      seed=config.sim_seed, first=config.sysid_first,
                      refine=config.sysid_refine, episode_minutes=config.episode_minutes,
                      workers=progress.workers)
    report = fit(cfg, train, val, out / "sysid",
                 lambda done, total: progress.report(f"sysid {name}", done, total))
    folders = {}
    for randomize in config.candidates:
        # folds whose fits agree share one collection
        folders[randomize] = _drawn_lab(config, around(report["fitted"], _ranges(randomize)),
                                        "fit", out, progress)
    names = {r: f.name for r, f in folders.items()}
    summary = {"fitted": report["fitted"], "train_ks": report["train"],
               "val_ks": report["val"],
               "data": next(iter(names.values())) if len(names) == 1 else names}
    return folders, summary


def lab_data(config: Config, fit: str, pooled: np.ndarray, folds: list[tuple], out: Path,
             progress: Progress) -> tuple[dict[str, list[Path]], dict]:
    """Per `randomize` candidate, each model seed's lab collection (Train.csv and Val.csv),
    and the fits made, by `fit`: `--sim`, or one collection for every seed (the scenario as
    written, or fitted on the real Train.csv), or one per fold fitted on that fold's training
    blocks only."""
    if config.sim is not None:
        return {PLAIN: [config.sim] * len(folds)}, {}
    if fit == "none":
        several = len(config.randomize) > 1
        return {r: [_collect(config, out / "data" / (
            f"sim-{task_key('sim2real-lab', 1, r)[:12]}" if several else "sim"), progress,
            None if r == PLAIN else r)] * len(folds)
            for r in config.candidates}, {}
    if fit == "train":
        from collectors.sysid import split_check

        n_train = len(read_csv(config.real / REAL_FILES[0]).poses)
        train, check = split_check(pooled) if config.train_only else (
            pooled[:n_train], pooled[n_train:])      # checked on Train's end, or on Val
        folders, fitted = _fitted_lab(config, train, check, out, "train", progress)
        return {r: [f] * len(folds) for r, f in folders.items()}, {"train": fitted}
    made: dict[int, tuple[dict[str, Path], dict]] = {}
    for fold, pool, val in folds:
        if fold not in made:
            made[fold] = _fitted_lab(config, pooled[pool], pooled[val], out, f"fold{fold}",
                                     progress)
    return {r: [made[fold][0][r] for fold, _, _ in folds] for r in config.candidates
            }, {f"fold{f}": fitted for f, (_, fitted) in sorted(made.items())}


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


@register
def run(config: Config, out: Path, progress: Progress) -> list[str]:
    """Collect (or take) the lab data, train every arm and fraction, plot; summary lines."""
    from estimators.retlo.files import pixels_to_world
    from viz.sim2real_figures import plot_curve

    with progress.stage("data"):
        pixels = validate(config)
        held = [fold_of(i, config.folds) for i in range(config.seeds)]
        folds = [(f, *cv_blocks(len(pixels), config.folds, f, config.val_share)[:2])
                 for f in held]
        labs, fits = {}, {}
        for fit in config.fits if config.arms != ("real",) else ():
            labs[fit], made = lab_data(config, fit, pixels, folds, out, progress)
            fits |= made
    pooled = pixels_to_world(pixels, DEFAULT_PX_PER_CM)
    later = [a for a in ARMS[1:] if a in config.arms]
    choose = len(config.candidates) > 1
    # the mixed arm alone trains sim models only to choose its lab data or to ablate it
    sim_models = bool({"sim", *FINETUNED} & set(config.arms)) or choose or \
        bool(config.ablate)
    per_share = sum(len(_candidates(config, a)) for a in later)
    total = config.seeds * (sim_models * len(labs) * len(config.candidates)
                            + per_share * len(config.fractions) + len(config.ablate))
    blocks, first = [], []
    for i in range(config.seeds):
        s = config.seed + i
        pool, val, test = cv_blocks(len(pooled), config.folds, fold_of(i, config.folds),
                                    config.val_share)
        blocks.append((s, pooled[pool], pooled[val], pooled[test]))
        if sim_models:
            first += [({"arm": "sim", "fit": fit, "randomize": r, "fraction": 0.0, "count": 0,
                        "seed": s},
                       _sim_task(config, s, lab[i], pooled[val], pooled[test], choose))
                      for fit, by_range in labs.items() for r, lab in by_range.items()]
    with progress.stage("models"):
        done = train_models(first, progress, total)
        sims = [{**meta, **json.loads((done[id(task)].folder / "report.json").read_text()),
                 "folder": done[id(task)].folder} for meta, task in first]
        # per fit and seed, the candidate best on the real validation block
        chosen = best_by(sims, lambda r: (r["fit"], r["seed"]), "select_head_cm")
        second: list[tuple[dict, ModelTask]] = []
        for i, (s, pool, val, test) in enumerate(blocks):
            sim = chosen.get((config.fits[0], s))
            ranges = sim["randomize"] if sim else config.candidates[0]
            lab = labs[config.fits[0]][ranges][i] if labs else None
            checkpoint = sim["folder"] / "model.pt" if sim else None
            for f in config.fractions:
                part = share(len(pool), f, i)
                second += [({"arm": arm, "fraction": f, "count": part.stop - part.start, "seed": s,
                             **tuned},
                            _arm_task(arm, config, s, pool[part], val, test, checkpoint, lab,
                                      **tuned))
                           for arm in later for tuned in _candidates(config, arm)]
        done |= train_models(second, progress, total, done)
        third = [({"ablate": group, "seed": s}, _sim_task(config, s, lab, val, test, False))
                 for group in config.ablate
                 for (s, _, val, test), lab in zip(blocks, _ablated_labs(
                     config, group, labs, chosen, out, progress), strict=True)
                 if lab is not None]
        done |= train_models(third, progress, total, done)
    reports, choices = choose_settings([
        {**meta, **json.loads((done[id(task)].folder / "report.json").read_text())}
        for meta, task in second], config)
    # the first fit's chosen sim models are the sim arm; the other fits' are kept apart
    picked = [{k: v for k, v in r.items() if k != "folder"} for r in chosen.values()]
    others = [r for r in picked if r["fit"] != config.fits[0]]
    if "sim" in config.arms:
        reports += [r for r in picked if r["fit"] == config.fits[0]]
    results = summarize(reports, config, len(pooled))
    if len(labs) > 1:
        results["sim_by_fit"] = by_fit(reports, others, config, results)
    if choose:
        results["ranges"] = by_range(sims, chosen, config)
    if config.ablate:
        results["ablations"] = by_ablation(
            [{**meta, **json.loads((done[id(task)].folder / "report.json").read_text())}
             for meta, task in third], chosen, config)
    results |= choices
    if fits:
        results["fits"] = fits
    write_json_atomic(out / "results.json", results)
    plot_curve(results, out / "sim2real.png")
    hits = set(progress.cache.hits)
    progress.record(models=len(reports),
                    sim_data=sorted({str(p) for by_range in labs.values()
                                     for lab in by_range.values() for p in lab}),
                    models_trained=len({t.key() for _, t in [*first, *second, *third]}
                                       - hits))
    lines = summary_lines(results)
    if not config.train_only:       # said where the run ends: a sealed file was read
        lines.append("these folds pool Val.csv, the sim-to-real work's sealed test (experiment "
                     "s2r-sealed): choose settings with --train-only, then look once there")
    return lines


def _profile(config: Config, lab: Path, randomize: str) -> dict:
    """The profile a lab collection was drawn from: the one written beside a fitted lab, or
    the `randomize` candidate's."""
    if config.fits[0] != "none":
        return json.loads((lab.parent / f"{lab.name}.profile.json").read_text())
    return _ranges(randomize) or {}


def _ablated_labs(config: Config, group: tuple[str, ...], labs: dict, chosen: dict,
                  out: Path, progress: Progress) -> list[Path | None]:
    """Each seed's lab collection with `group` switched off in the profile its sim model was
    chosen with (seeds whose profiles agree share one collection); None for a seed whose
    profile holds none of the group (nothing to switch off). The ablated lab draws its other
    parameters afresh: an episode's draws come in the profile's order, one per range."""
    folders: list[Path | None] = []
    for i in range(config.seeds):
        pick = chosen.get((config.fits[0], config.seed + i))
        ranges = pick["randomize"] if pick else config.candidates[0]
        lab = labs[config.fits[0]][ranges][i]
        own = _profile(config, lab, ranges)
        if not set(group) & set(own):
            folders.append(None)
            continue
        profile = {k: v for k, v in own.items() if k not in group}
        folders.append(_drawn_lab(config, profile, "ablate", out, progress))
    return folders


def _sim_task(config: Config, seed: int, lab: Path, val: np.ndarray, test: np.ndarray,
              choose: bool) -> ModelTask:
    """A sim-only model: trained on the lab's Train.csv, its checkpoint picked on the lab's
    Val.csv or on the fold's real validation block (`sim_select`); scored on `val` too where
    it is one of several candidates (`choose`)."""
    picked_on = val if config.sim_select == "real" else lab / "Val.csv"
    return ModelTask("sim", seed, config.epochs, lab / "Train.csv", picked_on, test,
                     chained=config.chained, precision=config.precision,
                     select=val if choose else None)


def _candidates(config: Config, arm: str) -> list[dict[str, Any]]:
    """The settings a real-data arm trains one model each of (`TUNED` that reach it, every
    combination of their candidates); [{}] for an arm none reaches."""
    combos: list[dict[str, Any]] = [{}]
    for tuned in (t for t in TUNED if arm in t.arms):
        combos = [{**c, tuned.name: v} for c in combos for v in getattr(config, tuned.name)]
    return combos


def _arm_task(arm: str, config: Config, seed: int, train: np.ndarray, val: np.ndarray,
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


def summarize(reports: list[dict], config: Config, n_real: int) -> dict:
    """Head and mean error (cm) per arm and fraction over seeds (and the Head's per seed, for
    paired comparisons between runs on the same folds); with the real arm, the
    sim-only / real-only ratio and, per fraction, the real-only data the fine-tuned model's error
    is worth."""
    out: dict = {"profile": asdict(config), "real_instances": n_real, "arms": {}}
    for arm in (a for a in ARMS if a in config.arms):
        out["arms"][arm] = {}
        for f in (0.0,) if arm == "sim" else config.fractions:
            cell = [r for r in reports if r["arm"] == arm and r["fraction"] == f]
            out["arms"][arm][f"{f:g}"] = {
                "head_cm": mean_std([r["head_cm"] for r in cell]),
                "mean_cm": mean_std([r["mean_cm"] for r in cell]),
                "count": max(r["count"] for r in cell),
                "head_cm_by_seed": {str(r["seed"]): r["head_cm"] for r in cell}}
    real = out["arms"].get("real")
    if real is None:
        return out
    full = real[f"{max(config.fractions):g}"]["head_cm"]["mean"]
    if "sim" in out["arms"]:
        out["sim_over_real"] = out["arms"]["sim"]["0"]["head_cm"]["mean"] / full
    out["equivalent_real_fraction"] = {
        f: equivalent_fraction(v["head_cm"]["mean"], config.fractions,
                               [real[f"{g:g}"]["head_cm"]["mean"] for g in config.fractions])
        for f, v in out["arms"].get("finetune", {}).items()}
    return out


def by_fit(reports: list[dict], others: list[dict], config: Config, results: dict) -> dict:
    """The sim-only Head error of every fit on the same folds, with its ratio to real only
    (where the real arm ran) and, per seed, for paired comparisons."""
    out = {}
    for fit in config.fits:
        cell = [r for r in [*reports, *others] if r["arm"] == "sim" and r.get("fit") == fit]
        out[fit] = {"head_cm": mean_std([r["head_cm"] for r in cell]),
                    "head_cm_by_seed": {str(r["seed"]): r["head_cm"] for r in cell}}
        if "real" in results["arms"]:
            real = results["arms"]["real"][f"{max(config.fractions):g}"]["head_cm"]["mean"]
            out[fit]["sim_over_real"] = out[fit]["head_cm"]["mean"] / real
    return out


def by_range(sims: list[dict], chosen: dict[tuple[str, int], dict], config: Config) -> dict:
    """Per fit, the `randomize` candidates' sim-only models: which each seed chose (on its
    fold's real validation block) and each candidate's Head error there and on the test
    block."""
    out = {}
    for fit in dict.fromkeys(r["fit"] for r in sims):
        cells = {r: [o for o in sims if o["fit"] == fit and o["randomize"] == r]
                 for r in config.candidates}
        out[fit] = {
            "chosen_by_seed": {str(s): c["randomize"] for (f, s), c in chosen.items()
                               if f == fit},
            "candidates": {r: {
                "select_head_cm": mean_std([o["select_head_cm"] for o in c]),
                "head_cm": mean_std([o["head_cm"] for o in c]),
                "select_head_cm_by_seed": {str(o["seed"]): o["select_head_cm"] for o in c},
                "head_cm_by_seed": {str(o["seed"]): o["head_cm"] for o in c}}
                for r, c in cells.items()}}
    return out


def by_ablation(reports: list[dict], chosen: dict[tuple[str, int], dict], config: Config
                ) -> dict:
    """Per switched-off group, the sim-only Head error and its difference to the lab's own
    sim model on the same seed, averaged to each fold (seeds s and s + folds share one) with
    the mean and 95 % interval over the folds, corrected for the training data they share
    (Nadeau-Bengio; none where no seed's profile held the group)."""
    lab = {s: r["head_cm"] for (f, s), r in chosen.items() if f == config.fits[0]}
    out = {}
    for group in config.ablate:
        cell = [r for r in reports if r["ablate"] == group]
        by_fold: dict[int, list[float]] = {}
        for r in cell:
            by_fold.setdefault(fold_of(r["seed"] - config.seed, config.folds), []).append(
                r["head_cm"] - lab[r["seed"]])
        out[",".join(group)] = {
            "head_cm": mean_std([r["head_cm"] for r in cell]),
            "head_cm_by_seed": {str(r["seed"]): r["head_cm"] for r in cell},
            "minus_lab": paired_interval([float(np.mean(d)) for d in by_fold.values()],
                                         cv_ratio(config.folds))}
    return out


def equivalent_fraction(error: float, fractions: tuple[float, ...], errors: list[float]
                        ) -> float | None:
    """The share of real data a real-only model needs to reach `error`: linear in log share
    between the measured fractions; None outside them (better than all of it, or worse than the
    smallest share)."""
    errs = np.minimum.accumulate(np.asarray(errors, float))    # more data never hurts
    if error < errs[-1] or error > errs[0]:
        return None
    i = int(np.searchsorted(-errs, -error))                   # first index with errs <= error
    if i == 0:
        return float(fractions[0])
    logf = np.log(np.asarray(fractions, float))
    e0, e1 = errs[i - 1], errs[i]
    w = (e0 - error) / (e0 - e1)
    return float(np.exp(logf[i - 1] + w * (logf[i] - logf[i - 1])))


def summary_lines(results: dict) -> list[str]:
    lines = []
    for arm, per in results["arms"].items():
        for f, v in per.items():
            h = v["head_cm"]
            share = "" if arm == "sim" else f" at {float(f) * 100:.0f} % real"
            lines.append(f"{arm:<9}{share:<14} Head {h['mean']:.2f} ± {h['std']:.2f} cm "
                         f"({h['n']} seeds)")
    for fit, ranges in results.get("ranges", {}).items():
        counts = Counter(ranges["chosen_by_seed"].values())
        lines.append(f"--randomize chosen per fold ({fit}): " + ", ".join(
            f"{Path(r).name} {n}x" for r, n in counts.most_common()))
    for tuned in TUNED:
        for arm, shares in results.get(tuned.table, {}).items():
            for f, cell in shares.items():
                counts = Counter(cell["chosen_by_seed"].values())
                lines.append(f"{arm} at {float(f) * 100:.0f} % real, {tuned.label} chosen per "
                             "seed: " + ", ".join(f"{w:g} {n}x" for w, n in counts.most_common()))
    for name, cell in results.get("ablations", {}).items():
        d = cell["minus_lab"]
        if d["mean"] is None:
            lines.append(f"without {name}: not in the lab's profile, nothing switched off")
            continue
        spread = "" if d["low"] is None else f" [{d['low']:+.2f}, {d['high']:+.2f}]"
        lines.append(f"without {name}: Head {d['mean']:+.2f} cm{spread} against the lab's "
                     f"({d['n']} folds)")
    if "sim_over_real" in results:
        lines.append(f"sim only / real only (100 %): {results['sim_over_real']:.2f}x")
    for f, g in results.get("equivalent_real_fraction", {}).items():
        worth = ("outside the measured range" if g is None
                 else f"worth {g * 100:.0f} % real-only")
        lines.append(f"fine-tuned on {float(f) * 100:.0f} % real: {worth}")
    return lines
