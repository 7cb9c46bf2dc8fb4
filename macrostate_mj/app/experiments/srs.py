"""`experiment srs`: chapter 3 (§3.4–3.5) on our `webots` scenario, as a cached task graph.

Datasets (3-robot teams, `profile.train` instances each, Table 3.1): Passive, Rand-Only at every σ
of Fig 3.4, and SRS with each pick policy (its first `ro_instances` are its RO phase). Dataset j
of every configuration uses the collection seed `seed * 1000 + j`: the same starts and Head
routes across configurations (common random numbers), so their differences are the Tail's.
One 3-robot validation set and one 5-robot test set (passive) serve every model, so the models
are compared on the same instances. Models: chapter 3's predictor (unidirectional LSTM, cos/sin
angles, ℓ = 10), trained on the first 33 / 66 / 100 % of a dataset with `models` seeds, selected
on the validation set, tested on the 5-robot set. Every dataset and model is a task whose output
is kept (`data/`, `models/`): a rerun after a kill resumes; models run on `--workers` or Ray.
"""

from __future__ import annotations

import json
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

from collectors.runner import CollectRequest, collect, finished
from collectors.srs import SRSRequest, collect_srs, episodes_for
from macrostate_mj.app.experiments import mean_std
from macrostate_mj.core.io import check_writable_dir, write_json_atomic, write_manifest
from macrostate_mj.core.parallel import runner_for
from macrostate_mj.formats.thymioloc import DEFAULT_PX_PER_CM, read_csv, to_world

PRODUCTS = ["results.json", "fig3_4.png", "fig3_5a.png", "fig3_5b.png", "fig3_6.png",
            "fig3_7.png", "manifest.json"]
SCENARIO = "webots"
RO_SIGMA = 0.75        # the Rand-Only baseline of Fig 3.5 (the best σ of §3.5.1)


@dataclass(frozen=True)
class SRSProfile:
    """How much of the chapter to run: `full` is Table 3.1's sizes, `quick` a smoke run."""

    train: int = 300
    val: int = 50
    test: int = 150
    test_robots: int = 5
    datasets: int = 3
    models: int = 3
    sigmas: tuple[float, ...] = (0.0, 0.25, 0.5, 0.75, 1.0, 1.25, 1.5)
    budgets: tuple[float, ...] = (1 / 3, 2 / 3, 1.0)
    picks: tuple[str, ...] = ("max", "q3", "q2", "med")
    ro_instances: int = 100
    k: int = 30
    epochs: int = 60
    episode_minutes: float = 5.0



PROFILES = {
    "full": SRSProfile(),
    # Fig 3.5b alone at Table 3.1's sizes: Passive, Rand-Only and SRS-Med, 3 datasets, 1 model
    "fig3.5b": SRSProfile(sigmas=(0.75,), picks=("med",), models=1),
    "quick": SRSProfile(train=12, val=6, test=6, datasets=1, models=1, sigmas=(0.0, 0.75),
                        budgets=(0.5, 1.0), picks=("max", "med"), ro_instances=6, k=8,
                        epochs=3, episode_minutes=1.0),
}


@dataclass(frozen=True)
class _Dataset:
    """One collection of the chapter; collected only when a task still needs it."""

    out: Path
    robots: int
    instances: int
    seed: int
    policy: str = "passive"     # the Tail's rule while collecting: passive or random
    sigma: float = 0.0

    @property
    def csv(self) -> Path:
        return self.out / "instances.csv"

    def request(self, workers: int, ray: str | None, profile: SRSProfile) -> CollectRequest:
        return CollectRequest(SCENARIO, self.robots, 0.0, self.seed, self.out, self.policy,
                              self.sigma, workers, ray, episode_minutes=profile.episode_minutes)

    def ensure(self, profile: SRSProfile, workers: int, ray: str | None) -> Path:
        """Collect unless done (each collection resumes shard by shard); the instances file."""
        req = self.request(workers, ray, profile)
        req = replace(req, minutes=episodes_for(req, self.instances) * profile.episode_minutes)
        if not finished(req):
            collect(req)
        return self.csv


@dataclass(frozen=True)
class _SRSDataset(_Dataset):
    """An SRS collection: its RO phase at the Rand-Only σ, then the `pick` policy's choices."""

    policy: str = "random"
    sigma: float = RO_SIGMA
    pick: str = "med"

    def ensure(self, profile: SRSProfile, workers: int, ray: str | None) -> Path:
        if not (self.out / "manifest.json").exists():
            from estimators.srs.novelty import NoveltyTraining  # torch, only when collecting

            collect_srs(SRSRequest(self.request(workers, ray, profile), self.pick,
                                   self.instances, profile.ro_instances, profile.k),
                        NoveltyTraining())
        return self.csv


def _datasets(profile: SRSProfile, data: Path, seed: int) -> dict[str, list[_Dataset]]:
    """Every configuration's training datasets; dataset j of each uses seed*1000 + j."""
    configs: dict[str, list[_Dataset]] = {}
    for j in range(profile.datasets):
        s = seed * 1000 + j
        configs.setdefault("passive", []).append(
            _Dataset(data / f"passive_d{j}", 3, profile.train, s, "passive"))
        for sigma in profile.sigmas:
            configs.setdefault(f"ro_{sigma:g}", []).append(
                _Dataset(data / f"ro_{sigma:g}_d{j}", 3, profile.train, s, "random", sigma))
        for pick in profile.picks:
            configs.setdefault(f"srs_{pick}", []).append(
                _SRSDataset(data / f"srs_{pick}_d{j}", 3, profile.train, s, pick=pick))
    return configs


def _train_task(task: dict) -> dict:
    """One model: train on the first `count` instances, select on val, test; cached as JSON."""
    path = Path(task["report"])
    if path.exists():
        return json.loads(path.read_text())
    from estimators.retlo.api import evaluate, fit
    from estimators.retlo.files import read_world
    from estimators.retlo.models import ModelConfig, TorchPredictor
    from estimators.retlo.train import TrainConfig

    model = ModelConfig(history=10, bidirectional=False, cos_sin=True)
    cfg = TrainConfig(epochs=task["epochs"], seed=task["seed"], model=model)
    net, info = fit([read_world(task["train"])[:task["count"]]], task["val"], cfg)
    report = evaluate(TorchPredictor(net), task["test"])
    report = {**report, "best_val_cm": info["best_val_cm"], "task": task["name"]}
    write_json_atomic(path, report)
    return report


def run_srs_experiment(profile: SRSProfile, out: Path, seed: int = 0, workers: int = 1,
                       ray: str | None = None) -> list[str]:
    """Collect, train, test and plot; returns summary lines. `out` has been checked.

    What a task leaves is small (`models/*.json`, `distances/*.json`) and is all a rerun
    needs: a dataset is collected (again) only while a model or a histogram still needs it, so
    a run resumes from those files alone, e.g. on a fresh machine from a copy kept in git.
    Configurations run one after another (datasets, then their models), Fig 3.5b's first, so
    a run cut short leaves whole configurations done and little to collect again."""
    from viz.srs_figures import plot_budgets, plot_distances, plot_sigma, plot_stepwise

    t0, trained = time.perf_counter(), 0
    data = check_writable_dir(out / "data")
    models = check_writable_dir(out / "models")
    hists = check_writable_dir(out / "distances")
    val = _Dataset(data / "val", 3, profile.val, seed * 1000 + 500, "passive")
    test = _Dataset(data / "test", profile.test_robots, profile.test, seed * 1000 + 900,
                    "passive")
    configs = _datasets(profile, data, seed)
    first = ["passive", f"ro_{RO_SIGMA:g}", "srs_med"]
    configs = {c: configs[c] for c in sorted(configs, key=lambda c: c not in first)}
    tasks = []
    for name, sets in configs.items():
        budgets = profile.budgets if name in _budgeted(profile) else (1.0,)
        for b in budgets:
            count = int(round(b * profile.train))
            for j, ds in enumerate(sets):
                for m in range(profile.models):
                    tag = f"{name}_b{round(100 * b)}_d{j}_m{m}"
                    tasks.append({"name": tag, "config": name, "budget": b, "train": str(ds.csv),
                                  "count": count, "val": str(val.csv), "test": str(test.csv),
                                  "seed": m, "epochs": profile.epochs, "dataset": ds,
                                  "report": str(models / f"{tag}.json")})
    shown = [c for c in ("srs_max", f"ro_{RO_SIGMA:g}") if c in configs]
    run = runner_for(ray)
    reports: dict[str, dict] = {}
    distances: dict[str, dict] = {}
    t_data = t_models = 0.0
    for name, sets in configs.items():       # one configuration at a time: see the docstring
        mine = [t for t in tasks if t["config"] == name]
        pending = [t for t in mine if not Path(t["report"]).exists()]
        hist = hists / f"{name}.json"
        needed = ([val, test] if pending else []) + [t["dataset"] for t in pending] + (
            sets if name in shown and not hist.exists() else [])
        t1 = time.perf_counter()
        for ds in dict.fromkeys(needed):      # in order, once each
            ds.ensure(profile, workers, ray)
        t2 = time.perf_counter()
        jobs = [{k: v for k, v in t.items() if k != "dataset"} for t in mine]
        reports.update((r["task"], r) for r in run(_train_task, jobs, workers))
        if name in shown:
            distances[name] = _distances(sets, profile, hist)
        t_data, t_models = t_data + t2 - t1, t_models + time.perf_counter() - t2
        trained += len(pending)

    results = _results(profile, tasks, reports)
    results["distances"] = distances
    write_json_atomic(out / "results.json", results)
    plot_sigma(results, out / "fig3_4.png")
    plot_budgets(results, [f"srs_{p}" for p in profile.picks], out / "fig3_5a.png")
    plot_budgets(results, ["passive", f"ro_{RO_SIGMA:g}", "srs_med"], out / "fig3_5b.png")
    plot_stepwise(results, out / "fig3_6.png")
    plot_distances(results, out / "fig3_7.png")
    timings = {"datasets": t_data, "models": t_models, "total": time.perf_counter() - t0}
    write_manifest(out, "experiment srs", {"profile": asdict(profile), "scenario": SCENARIO},
                   seed, timings, products=PRODUCTS, workers=workers, models_trained=trained)
    return _summary(results, timings)


def _budgeted(profile: SRSProfile) -> set[str]:
    """Configurations trained at every budget (Fig 3.5); the σ sweep only at 100 %."""
    return {"passive", f"ro_{RO_SIGMA:g}", *(f"srs_{p}" for p in profile.picks)}


def _results(profile: SRSProfile, tasks: list[dict], reports: dict[str, dict]) -> dict:
    """Per configuration and budget: Head and mean error (cm) mean ± std over datasets and
    models, and the step-wise Head and F2 errors."""
    cells: dict[str, dict[str, list[dict]]] = {}
    for t in tasks:
        cells.setdefault(t["config"], {}).setdefault(f"{t['budget']:.4f}",
                                                     []).append(reports[t["name"]])
    out: dict = {"profile": asdict(profile), "configs": {}}
    for config, per_budget in cells.items():
        out["configs"][config] = {}
        for budget, reps in sorted(per_budget.items()):
            steps = {}
            for robot in ("H", "F2"):
                if robot in reps[0]["per_robot_step_cm"]:
                    cols = zip(*(rep["per_robot_step_cm"][robot] for rep in reps), strict=True)
                    vals = [[x for x in col if x is not None] for col in cols]
                    steps[robot] = [float(np.mean(v)) if v else None for v in vals]
            out["configs"][config][budget] = {
                "instances": int(round(float(budget) * profile.train)),
                "head_cm": mean_std([r["per_robot_cm"]["H"] for r in reps]),
                "mean_cm": mean_std([r["mean_error_cm"] for r in reps]),
                "per_step_cm": steps,
                "first_step": reps[0]["first_step"], "step_s": reps[0]["step_s"]}
    return out


def _distances(sets: list[_Dataset], profile: SRSProfile, cache: Path) -> dict:
    """Fig 3.7: H–F and F–T distances (cm) in the first 66 % of a configuration's datasets
    (tracked instances); cached in `cache`."""
    if cache.exists():
        return json.loads(cache.read_text())
    count = int(round(2 / 3 * profile.train))
    w = np.concatenate([to_world(read_csv(ds.csv).poses[:count], DEFAULT_PX_PER_CM)
                        for ds in sets])
    out = {"H-F": np.linalg.norm(w[:, :, 0, :2] - w[:, :, 1, :2], axis=-1).ravel()
           .round(2).tolist(),
           "F-T": np.linalg.norm(w[:, :, 1, :2] - w[:, :, 2, :2], axis=-1).ravel()
           .round(2).tolist()}
    write_json_atomic(cache, out)
    return out


def _summary(results: dict, timings: dict[str, float]) -> list[str]:
    lines = []
    for config, per_budget in results["configs"].items():
        cells = [f"{c['instances']} inst. H {c['head_cm']['mean']:.1f} ± {c['head_cm']['std']:.1f}"
                 for c in per_budget.values()]
        lines.append(f"{config:<10} " + "; ".join(cells) + " cm")
    lines.append(f"datasets {timings['datasets']:.0f} s, models {timings['models']:.0f} s, "
                 f"total {timings['total']:.0f} s")
    return lines
