"""`experiment sim2real`: how far lab data carries a ReTLo model on real data, and how much real
data sim pre-training saves (issue 13's data-efficiency curve).

Real data: a folder of ThymioLoc 3-robot files, `Train.csv` then `Val.csv`, pooled in that order
and cut into `folds` contiguous blocks (instances overlap in time, so a random split would leak).
Model seed s is tested on block s mod `folds`, never used by any model of that seed; of the
other blocks, the last `val_share` selects the real-trained checkpoints and the rest is the real
training pool, of which the first 10 / 25 / 50 / 100 % are used. Three arms per seed:
- sim: trained and selected on a lab collection only (`collect --scenario lab --robots 3
  --split 80/20/0 [--randomize PROFILE]`, cached in `data/sim`, or `--sim DIR` with Train.csv
  and Val.csv);
- real: trained on a fraction of the pool, selected on the real validation block;
- finetune: the same seed's sim model trained further on the same fraction (`finetune_epochs`).
Every model is the LSTM of `train retlo --model lstm`; each is a task cached as JSON (and the
sim models as checkpoints), so a rerun after a kill resumes; `run.json` records what the cache
was made from (the lab scenario's constants among it), and a rerun with other inputs into the
same folder is refused.
"""

from __future__ import annotations

import hashlib
import json
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

from collectors.runner import CollectRequest, collect, finished
from macrostate_mj.app.experiments import mean_std
from macrostate_mj.chain.scenarios import get_scenario
from macrostate_mj.core.errors import UserError
from macrostate_mj.core.io import check_writable_dir, claim_run, write_json_atomic, write_manifest
from macrostate_mj.core.parallel import runner_for
from macrostate_mj.formats.thymioloc import DEFAULT_PX_PER_CM, read_csv

PRODUCTS = ["results.json", "sim2real.png", "manifest.json"]
ARMS = ("sim", "real", "finetune")
REAL_FILES = ("Train.csv", "Val.csv")


@dataclass(frozen=True)
class Sim2RealProfile:
    seeds: int = 5
    folds: int = 5
    fractions: tuple[float, ...] = (0.1, 0.25, 0.5, 1.0)
    val_share: float = 0.15
    epochs: int = 60
    finetune_epochs: int = 30
    finetune_lr: float = 5e-4
    sim_minutes: float = 100.0
    sim_seed: int = 31
    episode_minutes: float = 5.0


PROFILES = {
    "full": Sim2RealProfile(),
    "quick": Sim2RealProfile(seeds=2, fractions=(0.5, 1.0), epochs=2, finetune_epochs=1,
                             sim_minutes=6.0, episode_minutes=3.0),
}


def cv_blocks(n: int, folds: int, fold: int, val_share: float
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(train pool, validation, test) instance indices: test is contiguous block `fold` of
    `folds`; the last `val_share` of the remaining instances (in order) validate."""
    if not 0 <= fold < folds <= n:
        raise UserError(f"cannot cut {n} real instances into {folds} folds")
    edges = np.linspace(0, n, folds + 1).round().astype(int)
    test = np.arange(edges[fold], edges[fold + 1])
    rest = np.setdiff1d(np.arange(n), test)
    n_val = max(1, int(round(val_share * len(rest))))
    return rest[:-n_val], rest[-n_val:], test


def _require_splits(folder: Path, flag: str, hint: str) -> None:
    """One-line error unless `folder` holds Train.csv and Val.csv."""
    missing = [f for f in REAL_FILES if not (folder / f).is_file()]
    if missing:
        raise UserError(f"{flag} {folder} has no {missing[0]}; pass {hint}")


def read_real(folder: Path) -> np.ndarray:
    """The pooled real instances (metres), Train then Val; one-line errors otherwise."""
    from estimators.retlo.files import pixels_to_world

    _require_splits(folder, "--real", "the folder of the real ThymioLoc Train.csv and Val.csv")
    parts = [read_csv(folder / f).poses for f in REAL_FILES]
    if len({p.shape[1:] for p in parts}) != 1 or parts[0].shape[2] != 3:
        raise UserError(f"--real {folder}: Train.csv and Val.csv must both hold 3-robot "
                        "instances of the same length")
    return pixels_to_world(np.concatenate(parts), DEFAULT_PX_PER_CM)


def _sim_data(out: Path, sim: Path | None, profile: Sim2RealProfile, randomize: str | None,
              workers: int, ray: str | None) -> Path:
    """The folder of the lab Train.csv / Val.csv: `--sim`, or a cached lab collection."""
    if sim is not None:
        _require_splits(sim, "--sim", "a `collect --split` folder")
        return sim
    req = CollectRequest("lab", 3, profile.sim_minutes, profile.sim_seed, out, "passive",
                         workers=workers, ray=ray, split="80/20/0",
                         episode_minutes=profile.episode_minutes, randomize=randomize)
    if not finished(req):
        collect(req)
    return out


def _train_task(task: dict) -> dict:
    """One model: train (or fine-tune the sim model), select, test on its real fold; cached."""
    path = Path(task["report"])
    if _cached(task):
        return json.loads(path.read_text())
    from estimators.retlo.api import evaluate, fit
    from estimators.retlo.models import ModelConfig, TorchPredictor
    from estimators.retlo.train import TrainConfig, load_checkpoint, save_checkpoint

    real = np.load(task["real"])
    cfg = TrainConfig(epochs=task["epochs"], seed=task["seed"], model=ModelConfig(kind="lstm"))
    if task["arm"] == "sim":
        sim = Path(task["sim"])
        net, info = fit([sim / "Train.csv"], sim / "Val.csv", cfg)
        save_checkpoint(task["checkpoint"], net, DEFAULT_PX_PER_CM, cfg, info)
    else:
        init = None
        if task["arm"] == "finetune":
            init, _ = load_checkpoint(task["checkpoint"])
            cfg = replace(cfg, lr=task["lr"])
        net, info = fit([real["train"][:task["count"]]], real["val"], cfg, init=init)
    report = evaluate(TorchPredictor(net), real["test"])
    report = {"task": task["name"], "arm": task["arm"], "fraction": task["fraction"],
              "count": task["count"], "seed": task["seed"], "head_cm": report["per_robot_cm"]["H"],
              "mean_cm": report["mean_error_cm"], "best_val_cm": info["best_val_cm"],
              "epochs_run": info["epochs_run"]}
    write_json_atomic(path, report)
    return report


def _cached(task: dict) -> bool:
    """A task is done when its report is there, and a sim model's checkpoint too (fine-tuning
    starts from it)."""
    return Path(task["report"]).exists() and (
        task["arm"] != "sim" or Path(task["checkpoint"]).exists())


def run_sim2real(profile: Sim2RealProfile, real_dir: Path, out: Path, sim: Path | None = None,
                 randomize: str | None = None, workers: int = 1, ray: str | None = None
                 ) -> list[str]:
    """Collect (or take) the lab data, train every arm and fraction, plot; summary lines."""
    from collectors.randomize import Randomization
    from viz.sim2real_figures import plot_curve

    t0 = time.perf_counter()
    pooled = read_real(real_dir)
    if profile.folds > len(pooled):
        raise UserError(f"--real {real_dir} holds {len(pooled)} instances, fewer than "
                        f"{profile.folds} folds")
    if randomize is not None:
        if sim is not None:
            raise UserError("--randomize applies to the lab collection this command makes; "
                            "drop it or --sim")
        Randomization.parse(randomize)
    check_writable_dir(out)
    # The real data by content, not by path: the same run resumes from another checkout.
    claim_run(out, {"profile": asdict(profile),
                    "real_sha256": hashlib.sha256(np.ascontiguousarray(pooled)).hexdigest(),
                    "sim": None if sim is None else str(sim.resolve()), "randomize": randomize,
                    "lab": None if sim is not None else asdict(get_scenario("lab"))},
              "experiment sim2real")
    sim_dir = sim if sim is not None else check_writable_dir(out / "data" / "sim")
    models = check_writable_dir(out / "models")
    first, second = [], []
    for s in range(profile.seeds):
        pool, val, test = cv_blocks(len(pooled), profile.folds, s % profile.folds,
                                    profile.val_share)
        split = models / f"real_seed{s}.npz"
        if not split.exists():
            np.savez(split, train=pooled[pool], val=pooled[val], test=pooled[test])
        common = {"seed": s, "real": str(split), "sim": str(sim_dir),
                  "checkpoint": str(models / f"sim_seed{s}.pt")}
        first.append({**common, "name": f"sim_s{s}", "arm": "sim", "fraction": 0.0, "count": 0,
                      "epochs": profile.epochs, "report": str(models / f"sim_s{s}.json")})
        for f in profile.fractions:
            count = max(1, int(np.ceil(f * len(pool))))
            for arm, epochs in (("real", profile.epochs), ("finetune", profile.finetune_epochs)):
                name = f"{arm}_f{round(100 * f)}_s{s}"
                second.append({**common, "name": name, "arm": arm, "fraction": f,
                               "count": count, "epochs": epochs, "lr": profile.finetune_lr,
                               "report": str(models / f"{name}.json")})
    if not all(_cached(t) for t in first):      # the lab data only while a sim model needs it
        _sim_data(sim_dir, sim, profile, randomize, workers, ray)
    t_data = time.perf_counter() - t0
    run = runner_for(ray)
    t1 = time.perf_counter()
    reports = [*run(_train_task, first, workers), *run(_train_task, second, workers)]
    t_models = time.perf_counter() - t1
    results = summarize(reports, profile, len(pooled))
    write_json_atomic(out / "results.json", results)
    plot_curve(results, out / "sim2real.png")
    timings = {"data": t_data, "models": t_models, "total": time.perf_counter() - t0}
    write_manifest(out, "experiment sim2real", {"profile": asdict(profile),
                                                "real": str(real_dir), "sim": str(sim_dir),
                                                "randomize": randomize},
                   None, timings, products=PRODUCTS, workers=workers, models_trained=len(reports))
    return summary_lines(results)


def summarize(reports: list[dict], profile: Sim2RealProfile, n_real: int) -> dict:
    """Head and mean error (cm) per arm and fraction over seeds; the sim-only / real-only
    ratio; and, per fraction, the real-only data the fine-tuned model's error is worth."""
    out: dict = {"profile": asdict(profile), "real_instances": n_real, "arms": {}}
    for arm in ARMS:
        fracs = (0.0,) if arm == "sim" else profile.fractions
        out["arms"][arm] = {f"{f:g}": {
            "head_cm": mean_std([r["head_cm"] for r in reports
                               if r["arm"] == arm and r["fraction"] == f]),
            "mean_cm": mean_std([r["mean_cm"] for r in reports
                               if r["arm"] == arm and r["fraction"] == f]),
            "count": max([r["count"] for r in reports if r["arm"] == arm and r["fraction"] == f])}
            for f in fracs}
    real = out["arms"]["real"]
    full = real[f"{max(profile.fractions):g}"]["head_cm"]["mean"]
    out["sim_over_real"] = out["arms"]["sim"]["0"]["head_cm"]["mean"] / full
    out["equivalent_real_fraction"] = {
        f: equivalent_fraction(v["head_cm"]["mean"], profile.fractions,
                               [real[f"{g:g}"]["head_cm"]["mean"] for g in profile.fractions])
        for f, v in out["arms"]["finetune"].items()}
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
    lines.append(f"sim only / real only (100 %): {results['sim_over_real']:.2f}x")
    for f, g in results["equivalent_real_fraction"].items():
        worth = ("outside the measured range" if g is None
                 else f"worth {g * 100:.0f} % real-only")
        lines.append(f"fine-tuned on {float(f) * 100:.0f} % real: {worth}")
    return lines
