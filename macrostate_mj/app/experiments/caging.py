"""`experiment caging`: four Tails on `macrostate_mj/CagingTail-v0` (seed §2.5.4), through the
Gymnasium API only: success rate, time to cage, final spacing CV over the seeds, and Fig
2.3-style snapshots.

- passive: follows its neighbour (offset 0); the text says this team cannot cage;
- retlo: runs the §2.5 three-MLP ReTLo estimator live at 1 Hz (`OnlineChain`, trained here on
  the robotarium training runs of `experiment retlo-sim` and on rehearsal caging runs, cached)
  from its own and its neighbour's observed positions and the poses the team shares (at τ and
  every 5 s); when its last `chain.caging_mission.TRACK_STEPS` estimates of the Head fit a circle of
  about the boundary's size (`circling_centre`, loose `DETECTION` bounds), it encircles
  clockwise, against the Head: around the mean centre of the circles found, then, once its own
  sensor has the object (the `object` observation), around the object;
- oracle: the same Tail fed the Head's true position each second (privileged): the upper bound;
- random: a new uniform offset within the action bounds every second.

Per policy over the seeds: success rate (caged before the time limit), time to cage, the final
spacing's coefficient of variation (mean ± std), and Fig 2.3-style snapshots of the first seed.

This module composes: the scripted Tail and the oracle are `chain.caging_mission`'s, the
episode, the live head source and the estimator's runs `collectors.caging_runs`'s, the
recordings `viz.caging_video`'s, the estimator `estimators.retlo`'s.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from macrostate_mj.app.experiments import Progress, register
from macrostate_mj.app.params import Count, Positive, Seed, flag
from macrostate_mj.app.results.sources import record_of, source, stat
from macrostate_mj.core.cache import run_tasks, task_key
from macrostate_mj.core.evidence import Q, Table
from macrostate_mj.core.records import Record
from macrostate_mj.core.stats import show

if TYPE_CHECKING:
    import gymnasium

    from estimators.retlo.mlp import ChainedMLP
    from macrostate_mj.tails.caging import CagingTail

POLICIES = ("passive", "retlo", "oracle", "random")
PRODUCTS = ["results.json", "snapshots.png", "oracle_seed0.mp4", "retlo_seed0.mp4",
            "retlo_seed0.rrd"]


@dataclass(frozen=True)
class Config:
    seeds: int = field(default=20, metadata=flag(Count(None, "Episodes per Tail (seeds "
                                                      "0..seeds-1).")))
    time_limit: float = field(default=90.0, metadata=flag(Positive(
        None, "Simulated seconds per episode.", max=3600.0)))
    # the three MLPs (retlo-sim trains 500; 200 converge here)
    epochs: int = field(default=200, metadata=flag(Count(None, "Epochs of the ReTLo Tail's "
                                                         "three MLPs.")))
    train_steps: int = 800
    rehearsals: int = 40       # passive-Tail caging runs the estimator also learns from
    stride: int = 30           # the estimator's step in command ticks: 1 Hz (docs)
    seed: int = field(default=0, metadata=flag(Seed(0, "Seed of the MLPs' training and the "
                                                    "random Tail's draws.")))


PROFILES = {"full": Config(),
            "quick": Config(seeds=2, time_limit=60.0, epochs=20, train_steps=300, rehearsals=2)}


def run_episode(policy: str, seed: int, cfg: Config, model: ChainedMLP | None = None,
                frames_every: float | None = None, video: Path | None = None,
                rerun: Path | None = None) -> dict:
    """One seeded episode of one Tail; its outcome (and snapshots, a video with the object and
    the Tail's estimate of the Head drawn in, a rerun recording, when asked)."""
    import gymnasium

    from collectors.caging_runs import run_caging_episode
    from viz.caging_video import caging_recorders

    env = gymnasium.make("macrostate_mj/CagingTail-v0", time_limit=cfg.time_limit)
    obs, info = env.reset(seed=seed)
    tail, scored = _tail(policy, env, info, seed, cfg, model)
    task = env.unwrapped.task
    recorders = caging_recorders(task.sim, task.caging, video, rerun, lambda: tail.head_estimate)
    outcome = run_caging_episode(env, obs, info, tail, recorders, frames_every, scored)
    env.close()
    return {"policy": policy, "seed": seed, **outcome}


def _tail(policy: str, env: gymnasium.Env, info: dict, seed: int, cfg: Config,
          model: ChainedMLP | None
          ) -> tuple[CagingTail, Callable[[], tuple[int, np.ndarray]] | None]:
    """The Tail of `policy` on the reset `env`, and what scores its estimates of the Head (the
    ReTLo Tail's only)."""
    from estimators.retlo.online import OnlineChain
    from macrostate_mj.tails.caging import LiveHeadSource, ScriptedTail, oracle_source
    from macrostate_mj.tails.scripted import Passive, Uniform

    task, bound = env.unwrapped.task, env.action_space.high
    sim = task.sim
    if policy == "passive":
        return Passive(), None
    if policy == "random":               # a new offset each second
        rng = np.random.default_rng([cfg.seed, seed, 7])
        return Uniform(rng, bound, int(round(sim.cfg.command_hz))), None
    scored = None
    if policy == "retlo":
        steps = int(cfg.time_limit * sim.cfg.command_hz / cfg.stride) + 2
        live = LiveHeadSource(OnlineChain(model, sim.n, steps), info["team_at_start"],
                              cfg.stride)
        source, scored = live, live.latest
    else:
        source = oracle_source(sim, cfg.stride)
    tail = ScriptedTail(sim.cfg, sim.k_t, task.caging, float(bound[0]), source)
    return tail, scored


class EstimatorTask:
    """The ReTLo Tail's three MLPs as a cached task, keyed by everything its training reads
    (a `quick` estimator is never reused by a full run)."""

    stage: ClassVar[str] = "caging-estimator"
    version: ClassVar[int] = 1

    def __init__(self, cfg: Config):
        self.training = {"epochs": cfg.epochs, "train_steps": cfg.train_steps,
                         "rehearsals": cfg.rehearsals, "seconds": cfg.time_limit,
                         "stride": cfg.stride, "seed": cfg.seed}

    def key(self) -> str:
        return task_key(self.stage, self.version, self.training)

    @staticmethod
    def rehearse(runs: int, seconds: float) -> np.ndarray:
        """The rehearsal runs: passive-Tail caging episodes of the line team."""
        from collectors.caging_runs import rehearsal_runs

        return rehearsal_runs(runs, seconds)

    def compute(self) -> dict[str, bytes]:
        from collectors.caging_runs import estimator_runs
        from estimators.retlo.mlp import fit_runs

        t = self.training
        rng = np.random.default_rng(t["seed"])
        runs = estimator_runs(t["train_steps"], t["rehearsals"], t["seconds"], t["stride"], rng,
                              self.rehearse)
        return {"mlp.npz": fit_runs(runs, rng, t["epochs"]).to_npz()}


@dataclass(frozen=True)
class Results(Record):
    """Per Tail, the caged share of seeds, the time to cage and the final spacing, and each
    episode's record; a seed is one episode of each Tail."""

    UNIT = "seed"

    config: dict
    caging: dict
    table: dict[str, dict]
    retlo_over_oracle: Any
    episodes: list


@register
def run(cfg: Config, out: Path, progress: Progress) -> list[str]:
    """Every policy on every seed; results.json, snapshots.png, videos; summary lines."""
    from estimators.retlo.mlp import ChainedMLP
    from macrostate_mj.chain.caging_mission import CagingConfig
    from viz.caging_figures import plot_snapshots

    with progress.stage("train_retlo"):
        trained = next(run_tasks(progress.cache, [EstimatorTask(cfg)], progress.workers,
                                 progress.ray))
        model = ChainedMLP.from_npz(trained.folder / "mlp.npz")
    episodes, snapshots = [], {}
    done, total = 0, len(POLICIES) * cfg.seeds
    for policy in POLICIES:
        with progress.stage(f"episodes_{policy}"):
            for seed in range(cfg.seeds):
                first = seed == 0 and policy in ("oracle", "retlo")
                ep = run_episode(policy, seed, cfg, model, 5.0 if seed == 0 else None,
                                 out / f"{policy}_seed0.mp4" if first else None,
                                 out / "retlo_seed0.rrd" if first and policy == "retlo"
                                 else None)
                if "frames" in ep:
                    snapshots[policy] = ep.pop("frames")
                episodes.append(ep)
                done += 1
                progress.report("episodes", done, total)
    table = {p: _summary([e for e in episodes if e["policy"] == p]) for p in POLICIES}
    oracle = table["oracle"]["success_rate"]
    results = {"config": asdict(cfg), "caging": asdict(CagingConfig()), "table": table,
               "retlo_over_oracle": table["retlo"]["success_rate"] / oracle if oracle else None,
               "episodes": episodes}
    Results.of(results, "experiment caging").write(out)
    picked = [dict(f, label=p) for p in ("oracle", "retlo", "passive")
              for f in snapshots[p][1:5]]
    plot_snapshots(picked, CagingConfig(), (1.2, 0.7), out / "snapshots.png",
                   "seed 0, every 5 s: oracle Tail (top), ReTLo Tail (middle; circle: its "
                   "estimate of the Head), passive Tail (bottom)", zoom=0.25)
    return [f"{p:<8} caged {t['success_rate'] * 100:.0f} % of {t['seeds']} seeds, time "
            f"{show(t['time_to_cage_s'])} s, spacing CV {show(t['spacing_cv'], 3)}"
            for p, t in table.items()]


def _summary(eps: list[dict]) -> dict:
    caged = [e for e in eps if e["caged"]]

    def stat(values: list[float]) -> dict:
        return ({"mean": float(np.mean(values)), "std": float(np.std(values))} if values
                else {"mean": None, "std": None})
    return {"seeds": len(eps), "success_rate": len(caged) / len(eps),
            "time_to_cage_s": stat([e["time_to_cage_s"] for e in caged]),
            "spacing_cv": stat([e["spacing_cv"] for e in caged]),
            "faults": sum(e["fault"] is not None for e in eps),
            "head_estimate_error_m": stat([e["head_estimate_error_m"] for e in eps
                                           if e["head_estimate_error_m"] is not None])}


# Its tables and numbers as the docs show them ----------------------------------------

@source
def caging(folder: str) -> Table:
    """Every Tail of a caging run (or of `experiment caging-multi`'s arms): caged seeds, time
    to cage, spacing CV, the Head estimate."""
    table = record_of(folder).table
    rows = [["Tail", "caged", "time to cage (s)", "final spacing CV", "Head estimate (cm)"]]
    for tail, arm in table.items():
        caged = round(arm["success_rate"] * arm["seeds"])
        rows.append([tail, f"{caged} / {arm['seeds']}", stat(arm["time_to_cage_s"], ".1f"),
                     stat(arm["spacing_cv"], ".3f"),
                     stat(arm.get("head_estimate_error_m", {}), ".1f", 100)])
    return rows


@source
def caging_cell(folder: str, tail: str, field: str) -> Q:
    """A caging arm: `caged` (% of seeds), `seeds`, or `time` (mean ± std s, caged runs)."""
    arm = record_of(folder).table[tail]
    if field == "caged":
        return Q(100 * float(arm["success_rate"]), None, ".0f", "%")
    if field == "seeds":
        return Q(arm["seeds"], None, "d")
    time = arm["time_to_cage_s"]
    return Q(float(time["mean"]), float(time["std"]), ".1f", "s")

