"""`experiment retlo-sim`: the simulation chapter (§2.5) on the robotarium scenario: Fig 2.2,
chained MLPs trained on 3 robots estimating 5- and 6-robot chains.

Pipeline: 20 clean 3-robot treatments (5 Head presets × 4 k_t) → 5 noisy replicas → the three
chained networks → the six cases of Fig 2.2 (straight with 6 robots, a curve with 5 and 6, the
6-robot curve with true poses every 150 steps, and the 5-robot curve and the communicating case
with noisy inputs), estimated modularly. F2_one_step_mean_error is module 0 fed true inputs
(no recursion), to tell network error from accumulated error. per_step_errors.json holds every
case's error per robot and step. Both hold only deterministic numbers
(timings go to the manifest), so the same command gives the same file.

This module composes: the runs are `collectors.robotarium`'s and `collectors.robotarium_cases`',
the networks, their training and the chain estimates `estimators.retlo`'s, the figures
`viz.retlo_sim_figures`'.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from collectors.robotarium import K_T_FACTORS, noisy_replicas, training_runs, treatments
from collectors.robotarium_cases import CASES, case_runs, schedule, tail_view
from estimators.retlo.chain import estimate_chain, sync_steps
from estimators.retlo.heuristic import estimate_heuristic
from estimators.retlo.mlp import ChainedMLP, mse, train_mlp, training_pairs
from estimators.retlo.report import chain_errors, one_step_errors, summarize, unseen_names
from macrostate_mj.app.experiments import Progress, register
from macrostate_mj.app.params import Count, Seed, flag
from macrostate_mj.app.results.sources import ms, record, root, runs_of, source
from macrostate_mj.chain.planners import ROBOTARIUM_HEAD_PRESETS
from macrostate_mj.chain.scenario import ScenarioConfig
from macrostate_mj.chain.scenarios import get_scenario
from macrostate_mj.core.errors import UserError
from macrostate_mj.core.evidence import Table
from macrostate_mj.core.io import write_json_atomic
from macrostate_mj.core.records import Record

THRESHOLD = 0.03   # the robot diameter: estimates closer than this are accurate (§2.5.3)
PRODUCTS = ["results.json", "per_step_errors.json", "trajectories.png",
            *(f"case_{c.key}.png" for c in CASES)]


@dataclass(frozen=True)
class Config:
    """What `experiment retlo-sim` runs; recorded in the manifest and in results.json. An
    invalid one cannot be built, so a bad flag fails before the output folder is touched."""

    seed: int = field(default=0, metadata=flag(Seed(0, "Seed of every random draw (noise, "
                                                    "weights, batches).")))
    epochs: int = field(default=500, metadata=flag(Count(None, "Training epochs of the three "
                                                         "networks (§2.5.2.1).")))
    lr: float = 0.05
    momentum: float = 0.2
    batch: int = 128          # mini-batches: the seed's online updates (80k per epoch) are too
                              # slow on this CPU, and at lr 0.05 batches of 128 fit as well
    train_steps: int = field(default=800, metadata=flag(Count(
        None, "Steps (30 Hz ticks) per training treatment.", max=10**6)))
    test_steps: int = field(default=1600, metadata=flag(Count(
        None, "Steps (30 Hz ticks) per test case.", max=10**6)))
    replicas: int = 5
    noise: float = 0.001
    comm_every: int = 150
    k_t_factors: tuple[float, ...] = K_T_FACTORS
    scenario: str = "robotarium"

    def __post_init__(self) -> None:
        for name in ("epochs", "batch", "replicas", "comm_every"):
            if getattr(self, name) < 1:
                raise UserError(f"--{name.replace('_', '-')} must be at least 1, got "
                                f"{getattr(self, name)}")
        if self.train_steps < 10 or self.test_steps < 10:
            raise UserError("--train-steps and --test-steps must be at least 10")
        if self.lr <= 0 or self.noise < 0 or not 0 <= self.momentum < 1:
            raise UserError("need lr > 0, noise >= 0 and 0 <= momentum < 1")
        if self.scenario != "robotarium":
            raise UserError(f"retlo-sim runs on the robotarium scenario, not {self.scenario!r}")


PROFILES = {"full": Config(), "quick": Config(epochs=1, train_steps=20, test_steps=40)}


@dataclass(frozen=True)
class Results(Record):
    """Fig 2.2's cases: per case the chained MLPs' and the 2X heuristic's errors (m) per robot
    and over all, with the training's account; one run is one training seed."""

    UNIT = "seed"

    config: dict
    threshold: float
    training: dict
    cases: dict[str, dict]


@register
def run(cfg: Config, out: Path, progress: Progress) -> list[str]:
    """Generate, train, estimate, write results.json and the figures; summary lines."""
    from viz.retlo_sim_figures import plot_case, plot_trajectories

    scen = get_scenario(cfg.scenario)
    rng = np.random.default_rng(cfg.seed)
    with progress.stage("generate"):
        runs = training_runs(scen, cfg.train_steps, cfg.k_t_factors,
                             lambda i, n: progress.report("simulate training", i, n))
        base, targets = training_pairs(noisy_replicas(runs, cfg.replicas, cfg.noise, rng))
    with progress.stage("train"):
        model, history = train_mlp(base, targets, rng, cfg.epochs, cfg.lr, cfg.momentum,
                                   cfg.batch, lambda i, n: progress.report("train", i, n))
    results: dict = {"config": asdict(cfg), "threshold": THRESHOLD,
                     "training": _training(cfg, scen, runs, model, history, len(base)),
                     "cases": {}}
    with progress.stage("simulate_tests"):
        paths = case_runs(scen, cfg.test_steps,
                          lambda i, n: progress.report("simulate test runs", i, n))
    per_step: dict = {}
    lines = []
    with progress.stage("estimate"):
        for i, case in enumerate(CASES):
            poses, floor = paths[(case.n_robots, case.path)]
            sync = sync_steps(cfg.test_steps, cfg.comm_every if case.comm else None)
            sensed, synced, truth = tail_view(poses, sync, cfg.noise if case.noisy else 0.0, rng)
            names = unseen_names(case.n_robots)
            err = chain_errors(estimate_chain(model, sensed, synced, sync), truth)
            h_err = chain_errors(estimate_heuristic(sensed, synced, sync), truth)
            title = case.title.format(comm=cfg.comm_every)
            summary = summarize(err, names, THRESHOLD)
            results["cases"][case.key] = {
                "title": title, "n_robots": case.n_robots, "path": case.path, "floor": floor,
                "head_schedule": [list(s) for s in schedule(case.path, cfg.test_steps)],
                "comm_every": cfg.comm_every if case.comm else None, "noisy": case.noisy,
                **summary, "heuristic2x": summarize(h_err, names, THRESHOLD),
                "F2_one_step_mean_error": float(one_step_errors(model, truth).mean())}
            per_step[case.key] = {nm: [None if not np.isfinite(e) else round(float(e), 6)
                                       for e in err[:, j]] for j, nm in enumerate(names)}
            plot_case(err, names, sync[1:], THRESHOLD, f"({case.key}) {title}",
                      out / f"case_{case.key}.png")
            per = ", ".join(f"{nm} {v['mean_error']:.4f}/{100 * v['share_under']:.0f}%"
                            for nm, v in summary["per_robot"].items())
            lines.append(f"({case.key}) {title}: {per}")
            progress.report("estimate cases", i + 1, len(CASES))
        plot_trajectories({f"{p} ({n} robots)": run for (n, p), run in paths.items()},
                          scen.arena, out / "trajectories.png")
    Results.of(results, "experiment retlo-sim").write(out)
    write_json_atomic(out / "per_step_errors.json", per_step)
    progress.record(floors={f"{n}-{p}": floor for (n, p), (_, floor) in paths.items()})
    lines.append(f"mean error / share of steps under {THRESHOLD} m; results in {out}")
    return lines


def _training(cfg: Config, scen: ScenarioConfig, runs: np.ndarray, model: ChainedMLP,
              history: np.ndarray, samples: int) -> dict:
    """results.json's account of the training: its treatments, final loss, and RMSE on the
    clean (noise-free) runs."""
    clean_base, clean_targets = training_pairs(runs)
    return {
        "samples": samples,
        "treatments": [{"preset": t.preset, "v": ROBOTARIUM_HEAD_PRESETS[t.preset][0],
                        "omega": ROBOTARIUM_HEAD_PRESETS[t.preset][1], "k_t": t.k_t}
                       for t in treatments(scen, cfg.k_t_factors)],
        "final_loss_standardized": dict(zip(("x_H", "y_H", "theta_F"), history[-1].tolist(),
                                            strict=True)),
        "rmse_on_clean_runs": dict(zip(("x_H", "y_H", "theta_F"),
                                       np.sqrt(mse(model, clean_base, clean_targets)).tolist(),
                                       strict=True))}


# Its tables and numbers as the docs show them ----------------------------------------

@source
def retlo_sim(pattern: str) -> Table:
    """Fig 2.2: per case, the chained MLPs' mean and max error (cm) and the 2X heuristic's,
    mean ± std over the run folders `pattern` matches (one a training seed)."""
    runs = [record(Results, str(f.relative_to(root()))).cases for f in runs_of(pattern)]
    robots = sorted({r for c in runs[0].values() for r in c["per_robot"]}, key=_robot_order)
    rows = [["case", "all, mean", "all, max", *[f"{r}, mean" for r in robots], "2X, all mean"]]

    def cell(get: Callable[[dict], float]) -> str:
        return ms([100 * get(run) for run in runs], ".1f")

    for key, case in runs[0].items():
        rows.append([f"{key}: {case['title']}",
                     cell(lambda r, k=key: r[k]["all"]["mean_error"]),
                     cell(lambda r, k=key: r[k]["all"]["max_error"]),
                     *[cell(lambda r, k=key, b=b: r[k]["per_robot"][b]["mean_error"])
                       if b in case["per_robot"] else "" for b in robots],
                     cell(lambda r, k=key: r[k]["heuristic2x"]["all"]["mean_error"])])
    return rows


def _robot_order(name: str) -> tuple[int, int]:
    return (1, 0) if name == "H" else (0, int(name[1:]))

