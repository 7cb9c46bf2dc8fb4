"""`experiment uncertainty`: point against Gaussian ReTLo on the real 3-robot data, each seed's
LSTM with and without the Gaussian head, scored on a held-out share of Train.csv and on Val.csv,
the Gaussian seeds also as one deep ensemble.

Every model is the LSTM of `train retlo --model lstm` (a cached task of `experiment retlo`,
`TrainTask`): trained on the instances of Train.csv that `experiment retlo --holdout` keeps,
its checkpoint chosen (and a Gaussian's scale and regions fitted) on Val.csv; the held-out
share is never trained or selected on, so it is the independent score, and Val (which selected)
is reported beside it. Per set (`held`, `val`): each seed's mean error per head, the Gaussian
against the point mean, the Gaussian models' pooled calibration (coverage of their 50 and 90 %
regions, NLL) and the ensemble's (`estimators.retlo.mixture.GaussianEnsemble`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from estimators.retlo.api import predict, report
from estimators.retlo.files import read_world
from estimators.retlo.heads import GAUSSIAN, POINT
from estimators.retlo.models import ModelConfig, TorchPredictor
from estimators.retlo.train import TrainConfig, load_checkpoint
from macrostate_mj.app.experiments import Parallel, Progress, register
from macrostate_mj.app.experiments.retlo import TrainTask, holdout_split
from macrostate_mj.app.params import REAL_FOLDER, Count, Fraction, Precision, Seed, flag
from macrostate_mj.app.results.sources import (
    ms,
    record,
    source,
)
from macrostate_mj.core.cache import run_tasks
from macrostate_mj.core.errors import UserError
from macrostate_mj.core.evidence import Table
from macrostate_mj.core.paths import real_thymioloc
from macrostate_mj.core.records import Record
from macrostate_mj.core.stats import mean_std
from macrostate_mj.formats.thymioloc import DEFAULT_PX_PER_CM

REAL_DATA = ("retlo",)   # the published datasets it reads (`data fetch NAME`)
PRODUCTS = ["results.json"]
HEADS = {"point": POINT, "gaussian": GAUSSIAN}
PARTICLES = 32      # `evaluate retlo`'s Monte Carlo draws (3-robot data draws none)


@dataclass(frozen=True)
class Config:
    real: Path = field(default_factory=real_thymioloc, metadata=REAL_FOLDER)
    holdout: float = field(default=0.25, metadata=flag(Fraction(
        None, "The share of Train.csv held out as the independent test.")))
    seeds: int = field(default=5, metadata=flag(Count(None, "Model seeds per head "
                                                      "(seed..seed+seeds-1).")))
    epochs: int = field(default=60, metadata=flag(Count(None, "Epochs per training.")))
    seed: int = field(default=0, metadata=flag(Seed(0, "The first model seed.")))
    precision: str = field(default="fp32", metadata=flag(Precision()))

    def __post_init__(self) -> None:
        if not 0 < self.holdout < 0.9:
            raise UserError(f"--holdout must be in (0, 0.9): the held-out share is the "
                            f"independent test; got {self.holdout}", "holdout")


PROFILES = {"full": Config(), "quick": Config(seeds=2, epochs=1)}
PARALLEL = Parallel("one training each")


def missing(config: Config) -> str | None:
    """The input this run cannot start without, if it is absent (`experiment all` skips it)."""
    absent = [n for n in ("Train.csv", "Val.csv") if not (config.real / n).is_file()]
    return f"the ThymioLoc file {config.real / absent[0]}" if absent else None


@dataclass(frozen=True)
class Results(Record):
    """Per set (held-out share, Val.csv), each seed's point and Gaussian errors, the Gaussians'
    pooled calibration and the ensemble's."""

    UNIT = "seed"

    seeds: list[int]
    holdout: float
    n_instances: dict[str, int]
    held: dict
    val: dict


@register
def run(config: Config, out: Path, progress: Progress) -> list[str]:
    """Train both heads per seed, score them and the ensemble on both sets; summary lines."""
    px = DEFAULT_PX_PER_CM
    kept, held = holdout_split(read_world(config.real / "Train.csv", px), config.holdout)
    sets = {"held": held, "val": read_world(config.real / "Val.csv", px)}
    seeds = range(config.seed, config.seed + config.seeds)
    tasks = [TrainTask([kept], sets["val"], TrainConfig(
        epochs=config.epochs, seed=seed, model=ModelConfig(kind="lstm"),
        precision=config.precision), px, head) for head in HEADS.values() for seed in seeds]
    folders = {}
    with progress.stage("train"):
        for outcome in run_tasks(progress.cache, tasks, progress.workers, progress.ray):
            folders[tasks.index(outcome.task)] = outcome.folder
            progress.report("train", len(folders), len(tasks))
    models = {name: [TorchPredictor(load_checkpoint(folders[i * config.seeds + j] / "model.pt")[0])
                     for j in range(config.seeds)] for i, name in enumerate(HEADS)}
    with progress.stage("evaluate"):
        results = {part: _scores(models, world) for part, world in sets.items()}
    Results.of({"seeds": list(seeds), "holdout": config.holdout,
                                             "n_instances": {p: len(w) for p, w in sets.items()},
                                             **results}, "experiment uncertainty").write(out)
    return [f"{part}: point {mean_std(r['point_cm'])['mean']:.2f} cm, Gaussian "
            f"{mean_std(r['gaussian_cm'])['mean']:.2f} cm ({r['gaussian_vs_point']:+.1%}), "
            f"ensemble {r['ensemble_cm']:.2f} cm; 90 % regions hold "
            f"{r['ensemble_calibration']['coverage_90']:.2f} (ensemble)"
            for part, r in results.items()] + [f"results: {out / 'results.json'}"]


def _scores(models: dict, world) -> dict:
    """Each seed's mean error per head, the Gaussians' calibration, the ensemble's."""
    from estimators.retlo.mixture import GaussianEnsemble

    def scored(module, uncertain: bool) -> dict:
        est, cov = predict(module, world, gaussian=uncertain, particles=PARTICLES, seed=0)
        return report(module, world, est, cov if uncertain else None, PARTICLES, 0)

    point = [scored(m, False)["mean_error_cm"] for m in models["point"]]
    gauss = [scored(m, True) for m in models["gaussian"]]
    ensemble = scored(GaussianEnsemble(models["gaussian"]), True)
    gaussian_cm = [g["mean_error_cm"] for g in gauss]
    return {"point_cm": point, "gaussian_cm": gaussian_cm,
            "gaussian_vs_point": sum(gaussian_cm) / sum(point) - 1,
            "gaussian_calibration": [g["calibration"]["pooled"] for g in gauss],
            "ensemble_cm": ensemble["mean_error_cm"],
            "ensemble_calibration": ensemble["calibration"]["pooled"]}


# Its tables and numbers as the docs show them ----------------------------------------

@source
def uncertainty(folder: str, split: str) -> Table:
    """Point against Gaussian ReTLo (and their ensemble): mean error (cm) and calibration."""
    data = getattr(record(Results, folder), split)
    cal = data["gaussian_calibration"]
    rows = [["model", "mean error (cm)", "coverage_50", "coverage_90", "NLL"]]
    rows.append(["point", ms(data["point_cm"], ".2f"), "", "", ""])
    rows.append(["Gaussian", ms(data["gaussian_cm"], ".2f"),
                 ms([c["coverage_50"] for c in cal], ".2f"),
                 ms([c["coverage_90"] for c in cal], ".2f"), ms([c["nll"] for c in cal], ".2f")])
    ens = data["ensemble_calibration"]
    rows.append(["ensemble of the Gaussians", f"{data['ensemble_cm']:.2f}",
                 f"{ens['coverage_50']:.2f}", f"{ens['coverage_90']:.2f}", f"{ens['nll']:.2f}"])
    return rows

