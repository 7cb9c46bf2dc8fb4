"""`experiment srs`: chapter 3 (§3.4–3.5) on our `webots` scenario, as a cached task graph:
Table 3.1, Fig 3.4 (σ sweep), Fig 3.5a/b (policies over budgets), Fig 3.6 (step-wise, 5 robots)
and Fig 3.7 (distance histograms); it resumes after an interruption.

Datasets (3-robot teams, `config.train` instances each, Table 3.1): Passive, Rand-Only at every σ
of Fig 3.4, and SRS with each pick policy (its first `ro_instances` are its RO phase). Dataset j
of every configuration uses the collection seed `seed * 1000 + j`: the same starts and Head
routes across configurations (common random numbers), so their differences are the Tail's.
One 3-robot validation set and one 5-robot test set (passive) serve every model, so the models
are compared on the same instances. Models: chapter 3's predictor (unidirectional LSTM, cos/sin
angles, ℓ = 10), trained on the first 33 / 66 / 100 % of a dataset with `models` seeds, selected
on the validation set, tested on the 5-robot set.

Every dataset is a `collect` (or `collect --policy srs`) run in its own folder (`data/<name>/`,
resumed episode by episode); every model a cached task (`cache/srs-model/<key>/report.json`)
keyed by its training settings and the content of its data, so a rerun after a kill trains
only what is missing, and identical training data trains once (Rand-Only at σ = 0 is Passive;
an SRS dataset's first `ro_instances` are Rand-Only's). Models run on `--workers` or Ray.
`models/<config>_b<budget %>_d<dataset>_m<model seed>.json` keeps each model's report as its
task wrote it, so a claim can pair configurations model by model.
"""

from __future__ import annotations

import json
import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from collectors.runner import CollectRequest, collect, finished
from collectors.srs_collection import SRSRequest, collect_srs, episodes_for, finished_srs
from macrostate_mj.app.experiments import Parallel, Progress, register
from macrostate_mj.app.experiments.srs.record import Results
from macrostate_mj.app.params import Count, Precision, Seed, flag
from macrostate_mj.chain.scenarios import ScenarioRef
from macrostate_mj.core.cache import ShipsFiles, run_tasks, task_key
from macrostate_mj.core.errors import RunFailure
from macrostate_mj.core.io import write_text_atomic
from macrostate_mj.core.stats import mean_std
from macrostate_mj.formats.thymioloc import DEFAULT_PX_PER_CM, read_csv, to_world

PRODUCTS = ["results.json", "fig3_4.png", "fig3_5a.png", "fig3_5b.png", "fig3_6.png",
            "fig3_7.png", "models"]
MODEL_REPORT = "{config}_b{percent}_d{dataset}_m{model}.json"   # models/: one report a model
RO_SIGMA = 0.75        # the Rand-Only baseline of Fig 3.5 (the best σ of §3.5.1)


@dataclass(frozen=True)
class Config:
    """How much of the chapter to run: `full` is Table 3.1's sizes, `quick` a smoke run."""

    train: int = 300
    val: int = 50
    test: int = 150
    test_robots: int = 5
    datasets: int = 3
    models: int = 1        # model seeds a dataset: Fig 3.5's 3 models are one per dataset
    sigmas: tuple[float, ...] = (0.0, 0.25, 0.5, 0.75, 1.0, 1.25, 1.5)
    budgets: tuple[float, ...] = (1 / 3, 2 / 3, 1.0)
    picks: tuple[str, ...] = ("max", "q3", "q2", "med")
    ro_instances: int = 100
    k: int = 30
    epochs: int = 60
    episode_minutes: float = 5.0
    seed: int = field(default=0, metadata=flag(Seed(0, "Experiment seed; dataset j of every "
                                                    "configuration uses seed*1000+j.")))
    # the models' training arithmetic (`estimators.precision`)
    precision: str = field(default="fp32", metadata=flag(Precision()))
    group: int = field(default=1, metadata=flag(Count(
        None, "Models of one shape trained together, this many at a time (for a GPU; on a CPU "
        "chapter 3's LSTM gains little: `bench --only ensemble`).", max=64)))
    scenario: ScenarioRef = "webots"   # every collection's world: a built-in, a file or a config


# the validation and test sets' collection seeds, past every training dataset's (seed*1000 + j)
VAL_SEED, TEST_SEED = 500, 900
PARALLEL = Parallel("collections and trainings")
PROFILES = {
    "full": Config(),
    # the text's protocol with 3 model seeds a dataset (9 models a cell, as results/srs_full)
    "full-seeds": Config(models=3),
    # Fig 3.5b alone at Table 3.1's sizes: Passive, Rand-Only and SRS-Med, 3 datasets, 1 model
    "fig3.5b": Config(sigmas=(0.75,), picks=("med",)),
    "quick": Config(train=12, val=6, test=6, datasets=1, sigmas=(0.0, 0.75),
                    budgets=(0.5, 1.0), picks=("max", "med"), ro_instances=6, k=8,
                    epochs=3, episode_minutes=1.0),
}


@dataclass(frozen=True)
class Dataset:
    """One collection of the chapter, a `collect` run in its own folder."""

    out: Path
    robots: int
    instances: int
    seed: int
    policy: str = "passive"     # the Tail's rule while collecting: passive or random
    sigma: float = 0.0

    @property
    def csv(self) -> Path:
        return self.out / "instances.csv"

    def request(self, config: Config, workers: int, ray: str | None) -> CollectRequest:
        # overwrite: the folder is this experiment's; a collection of another config there
        # (another profile) is replaced, its episodes kept in its cache
        return CollectRequest(config.scenario, self.robots, 0.0, self.seed, self.out,
                              self.policy, self.sigma, workers, ray, overwrite=True,
                              episode_minutes=config.episode_minutes)

    def ensure(self, config: Config, workers: int, ray: str | None) -> Path:
        """Collect unless this very collection finished (it resumes episode by episode); the
        instances file."""
        req = self.request(config, workers, ray)
        req = replace(req, minutes=episodes_for(req, self.instances) * config.episode_minutes)
        if not finished(req):
            collect(req)
        return self.csv


@dataclass(frozen=True)
class _SRSDataset(Dataset):
    """An SRS collection: its RO phase at the Rand-Only σ, then the `pick` policy's choices."""

    policy: str = "random"
    sigma: float = RO_SIGMA
    pick: str = "med"

    def ensure(self, config: Config, workers: int, ray: str | None) -> Path:
        from estimators.srs.novelty import NoveltyTraining  # torch, only when collecting

        req = SRSRequest(self.request(config, workers, ray), self.pick, self.instances,
                         config.ro_instances, config.k)
        novelty = NoveltyTraining()
        if not finished_srs(req, novelty):
            collect_srs(req, novelty)
        return self.csv


def _datasets(config: Config, data: Path) -> dict[str, list[Dataset]]:
    """Every configuration's training datasets; dataset j of each uses seed*1000 + j."""
    configs: dict[str, list[Dataset]] = {}
    for j in range(config.datasets):
        s = config.seed * 1000 + j
        configs.setdefault("passive", []).append(
            Dataset(data / f"passive_d{j}", 3, config.train, s, "passive"))
        for sigma in config.sigmas:
            configs.setdefault(f"ro_{sigma:g}", []).append(
                Dataset(data / f"ro_{sigma:g}_d{j}", 3, config.train, s, "random", sigma))
        for pick in config.picks:
            configs.setdefault(f"srs_{pick}", []).append(
                _SRSDataset(data / f"srs_{pick}_d{j}", 3, config.train, s, pick=pick))
    return configs


class ModelTask(ShipsFiles):
    """One model: chapter 3's predictor trained on `train` (the first instances of a dataset,
    metres), selected on `val`, tested on `test`. Keyed by its training settings and the content
    of its data (the instances it trains on, the bytes of the two CSVs), not by their names:
    identical data trains once (an SRS dataset's first `ro_instances` are the Rand-Only
    dataset's, Rand-Only at σ = 0 is Passive)."""

    stage: ClassVar[str] = "srs-model"
    version: ClassVar[int] = 1
    shipped: ClassVar[tuple[str, ...]] = ("val", "test")

    def __init__(self, train: np.ndarray, val: Path, test: Path, epochs: int, seed: int,
                 precision: str = "fp32"):
        self.train, self.val, self.test = train, val, test
        self.epochs, self.seed, self.precision = epochs, seed, precision
        self._key: str | None = None

    def train_config(self) -> Any:
        from estimators.retlo.models import ModelConfig
        from estimators.retlo.train import TrainConfig

        model = ModelConfig(history=10, bidirectional=False, cos_sin=True)
        return TrainConfig(epochs=self.epochs, seed=self.seed, model=model,
                           precision=self.precision)

    def key(self) -> str:
        if self._key is None:
            self._key = task_key(self.stage, self.version, self.train_config(),
                                 [self.train, self.val, self.test])
        return self._key

    def compute(self) -> dict[str, bytes]:
        from estimators.retlo.api import fit

        net, info = fit([self.train], self.val, self.train_config())
        return self._report(net, info)

    def _report(self, net: Any, info: dict) -> dict[str, bytes]:
        from estimators.retlo.api import evaluate
        from estimators.retlo.models import TorchPredictor

        report = {**evaluate(TorchPredictor(net), self.test), "best_val_cm": info["best_val_cm"]}
        return {"report.json": json.dumps(report).encode()}

    def group(self) -> tuple:
        """Models of one shape on data of one shape train together (seeds and datasets)."""
        return (self.train.shape, str(self.val), str(self.test), self.epochs)

    @classmethod
    def compute_group(cls, tasks: list[ModelTask]) -> list[dict[str, bytes]]:
        from estimators.retlo.ensemble import Job, train_many
        from estimators.retlo.files import read_world

        val = read_world(tasks[0].val)
        trained = train_many([Job([t.train], val, t.train_config()) for t in tasks])
        return [t._report(net, info) for t, (net, info) in zip(tasks, trained, strict=True)]


@dataclass(frozen=True)
class _Cell:
    """A model's report and where it goes: its configuration and budget."""

    config: str
    budget: float
    key: str
    report: dict


@register
def run(config: Config, out: Path, progress: Progress) -> list[str]:
    """Collect, train, test and plot; returns summary lines.

    Configurations run one after another (their datasets, then their models), Fig 3.5b's
    first, so a run cut short leaves whole configurations done."""
    from estimators.retlo.files import read_world
    from viz.srs_figures import plot_all

    t0 = time.perf_counter()
    data = out / "data"
    val = Dataset(data / "val", 3, config.val, config.seed * 1000 + VAL_SEED, "passive")
    test = Dataset(data / "test", config.test_robots, config.test, config.seed * 1000 + TEST_SEED,
                    "passive")
    configs = _datasets(config, data)
    first = ["passive", f"ro_{RO_SIGMA:g}", "srs_med"]
    configs = {c: configs[c] for c in sorted(configs, key=lambda c: c not in first)}
    shown = [c for c in ("srs_max", f"ro_{RO_SIGMA:g}") if c in configs]
    cells: list[_Cell] = []
    distances: dict[str, dict] = {}
    trained: set[str] = set()
    resumed = 0
    total = sum(len(sets) * config.models * len(_budgets(config, name))
                for name, sets in configs.items())
    for name, sets in configs.items():       # one configuration at a time: see the docstring
        with progress.stage("datasets"):
            for ds in dict.fromkeys([val, test, *sets]):      # in order, once each
                ds.ensure(config, progress.workers, progress.ray)
        worlds = [read_world(ds.csv) for ds in sets]
        mine = [(b, ModelTask(w[:int(round(b * config.train))], val.csv, test.csv,
                              config.epochs, m, config.precision),
                 MODEL_REPORT.format(config=name, percent=round(b * 100), dataset=d, model=m))
                for b in _budgets(config, name) for d, w in enumerate(worlds)
                for m in range(config.models)]
        reports: dict[int, dict] = {}         # id(task) -> its report
        texts: dict[int, str] = {}            # id(task) -> its report as the task wrote it
        with progress.stage("models"):
            for outcome in run_tasks(progress.cache, [t for _, t, _ in mine],
                                     progress.workers, progress.ray, config.group):
                if outcome.folder is None:
                    raise RunFailure(f"a model of {name} failed: {outcome.failure}")
                if not outcome.cached:
                    trained.add(outcome.task.key())
                resumed += outcome.cached
                text = (outcome.folder / "report.json").read_text()
                reports[id(outcome.task)] = json.loads(text)
                texts[id(outcome.task)] = text
                progress.report("models", len(cells) + len(reports), total, resumed)
        cells += [_Cell(name, b, t.key(), reports[id(t)]) for b, t, _ in mine]  # task order
        (out / "models").mkdir(exist_ok=True)     # each model's report, as its task wrote it
        for _, t, file in mine:
            write_text_atomic(out / "models" / file, texts[id(t)])
        if name in shown:
            distances[name] = _distances(sets, config)

    results = _results(config, cells)
    results["distances"] = distances
    Results.of(results, "experiment srs").write(out)
    with progress.stage("figures"):
        plot_all(results, out, list(config.picks))
    progress.record(models=len(cells),
                    models_distinct=len({c.key for c in cells}),
                    models_trained=len(trained))
    timings = {k: progress.run.timings.get(k, 0.0) for k in ("datasets", "models")}
    return _summary(results, {**timings, "total": time.perf_counter() - t0})


def _budgets(config: Config, name: str) -> tuple[float, ...]:
    """Configurations trained at every budget (Fig 3.5); the σ sweep only at 100 %."""
    budgeted = {"passive", f"ro_{RO_SIGMA:g}", *(f"srs_{p}" for p in config.picks)}
    return config.budgets if name in budgeted else (1.0,)


def _results(config: Config, cells: list[_Cell]) -> dict:
    """Per configuration and budget: the error of all predictions (F2, F3 and Head on the
    5-robot test: the dissertation's metric for Fig 3.4-3.5, §2.6.3.1) and the Head's alone
    (cm), mean ± std over datasets and models, and the step-wise Head and F2 errors."""
    grouped: dict[str, dict[str, list[dict]]] = {}
    for c in cells:
        grouped.setdefault(c.config, {}).setdefault(f"{c.budget:.4f}",
                                                    []).append(c.report)
    out: dict = {"profile": asdict(config), "baseline": f"ro_{RO_SIGMA:g}", "configs": {}}
    for name, per_budget in grouped.items():
        out["configs"][name] = {}
        for budget, reps in sorted(per_budget.items()):
            steps = {}
            for robot in ("H", "F2"):
                if robot in reps[0]["per_robot_step_cm"]:
                    cols = zip(*(rep["per_robot_step_cm"][robot] for rep in reps), strict=True)
                    vals = [[x for x in col if x is not None] for col in cols]
                    steps[robot] = [float(np.mean(v)) if v else None for v in vals]
            out["configs"][name][budget] = {
                "instances": int(round(float(budget) * config.train)),
                "head_cm": mean_std([r["per_robot_cm"]["H"] for r in reps]),
                "all_predictions_cm": mean_std([r["mean_error_cm"] for r in reps]),
                "per_step_cm": steps,
                "first_step": reps[0]["first_step"], "step_s": reps[0]["step_s"]}
    return out


def _distances(sets: list[Dataset], config: Config) -> dict[str, list[float]]:
    """Fig 3.7: H–F and F–T distances (cm) in the first 66 % of a configuration's datasets
    (tracked instances)."""
    count = int(round(2 / 3 * config.train))
    w = np.concatenate([to_world(read_csv(ds.csv).poses[:count], DEFAULT_PX_PER_CM)
                        for ds in sets])
    return {"H-F": np.linalg.norm(w[:, :, 0, :2] - w[:, :, 1, :2], axis=-1).ravel()
            .round(2).tolist(),
            "F-T": np.linalg.norm(w[:, :, 1, :2] - w[:, :, 2, :2], axis=-1).ravel()
            .round(2).tolist()}


def _summary(results: dict, timings: dict[str, float]) -> list[str]:
    lines = []
    for name, per_budget in results["configs"].items():
        cells = [f"{c['instances']} inst. all {c['all_predictions_cm']['mean']:.1f} ± "
                 f"{c['all_predictions_cm']['std']:.1f}, H {c['head_cm']['mean']:.1f}"
                 for c in per_budget.values()]
        lines.append(f"{name:<10} " + "; ".join(cells) + " cm")
    lines.append(f"datasets {timings['datasets']:.0f} s, models {timings['models']:.0f} s, "
                 f"total {timings['total']:.0f} s")
    return lines
