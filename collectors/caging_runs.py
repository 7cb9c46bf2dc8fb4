"""Caging runs (seed §2.5.4): one episode of a Tail (`macrostate_mj.tails`) on
`macrostate_mj/CagingTail-v0`, and the simulated runs the Tail's estimator learns from.

This layer sits beside `macrostate_mj.env`, independent of it, and above `estimators`: the caller
makes the environment and the estimator's online chain and passes them in (any object with
their methods will do), and builds the recorders (`viz.caging_video`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Protocol

import gymnasium
import numpy as np

from collectors.robotarium import K_T_FACTORS, noisy_replicas, training_runs
from macrostate_mj.chain.caging_mission import CagingConfig, CagingMission, cage_report, start_poses
from macrostate_mj.chain.scenarios import SCENARIOS
from macrostate_mj.chain.sim import ChainSim, Every
from macrostate_mj.chain.team import (
    BranchedSim,
    TeamCaging,
    ring_order,
    split_branches,
    team_start_poses,
)
from macrostate_mj.chain.world import build_world
from macrostate_mj.tails.caging import CagingTail

ARENA = SCENARIOS["robotarium"]    # the caging mission's world (§2.5.4), as the CagingTail id's


class Recorder(Protocol):
    def capture(self, sim: ChainSim) -> None: ...

    def finish(self) -> None: ...


def run_caging_episode(env: gymnasium.Env, obs: dict, info: dict, tail: CagingTail,
                       recorders: Sequence[tuple[int, Recorder]] = (),
                       frames_every: float | None = None,
                       scored: Callable[[], tuple[int, np.ndarray]] | None = None) -> dict:
    """Run a reset caging environment (`obs`, `info` from its reset) to its end with `tail`;
    the outcome: caged, when, the final spacing's CV, when the Tail detected the circling, the
    mean error of the estimates `scored` gives (tick, Head), the fault; with `frames_every`
    (s), `frames`: snapshots for the figures. Each recorder captures every so many ticks and
    is finished."""
    task = env.unwrapped.task
    sim = task.sim
    frames, next_frame, done = [], 0.0, False
    estimate = None
    heads, errors = [], []            # the Head's true track, the scored estimates' errors
    tick = 0
    while not done:
        t = sim.time
        if frames_every is not None and t >= next_frame - 1e-9:
            frames.append({"t": t, "poses": sim.poses.copy(), "head_estimate":
                           None if estimate is None else estimate.copy()})
            next_frame += frames_every
        heads.append(sim.poses[0, :2].copy())
        action = tail.act(obs, {**info, "t": t})
        estimate = tail.head_estimate
        if scored is not None and estimate is not None:
            at, head = scored()
            errors.append(float(np.linalg.norm(head - heads[at])))
        for every, recorder in recorders:
            if tick % every == 0:
                recorder.capture(sim)
        obs, _, terminated, truncated, info = env.step(action)
        done = terminated or truncated
        tick += 1
    report = cage_report(sim.poses, task.caging)
    out = {"caged": info["caged_at"] is not None, "time_to_cage_s": info["caged_at"],
           "spacing_cv": report["spacing_cv"], "detected_at_s": tail.detected_at,
           "head_estimate_error_m": float(np.mean(errors)) if errors else None,
           "fault": info["fault"]}
    if frames_every is not None:
        frames.append({"t": sim.time, "poses": sim.poses.copy(), "head_estimate": estimate})
        out["frames"] = frames
    for _, recorder in recorders:
        recorder.finish()
    return out


def rehearsal_runs(runs: int, seconds: float) -> np.ndarray:
    """Caging episodes with a passive Tail (seeds 10000.., never an evaluation seed), every
    consecutive three robots as a 3-robot module run: (runs * (n - 2), steps, 3, 3), H first."""
    caging = CagingConfig()
    world = build_world(ARENA, 6)
    sim = ChainSim(world, mission=CagingMission(caging))
    return _rehearse(sim, runs, seconds, [np.arange(sim.n)],
                     lambda rng: start_poses(caging, sim.n, sim.cfg.spacing, rng,
                                             sim.cfg.arena))


def team_rehearsal_runs(runs: int, seconds: float) -> np.ndarray:
    """As `rehearsal_runs`, of the two-chain caging team (`chain.team`, 6 robots, both Tails
    passive: the Head parks at the object): every three consecutive robots of either chain."""
    caging = CagingConfig()
    world = build_world(ARENA, 6)
    branches = split_branches(6, 2)
    sim = BranchedSim(world, branches, mission=TeamCaging(caging, ring_order(branches)))
    return _rehearse(sim, runs, seconds, branches,
                     lambda rng: team_start_poses(caging, branches, sim.cfg.spacing, rng,
                                                  sim.cfg.arena))


def _rehearse(sim: ChainSim, runs: int, seconds: float, chains: list[np.ndarray],
              start: Callable[[np.random.Generator], np.ndarray]) -> np.ndarray:
    """`runs` episodes of `sim` (seeds 10000..) from `start`, logged at the log rate; each
    chain's (Head first) consecutive triples as module runs."""
    out = []
    for i in range(runs):
        rng = np.random.default_rng(10_000 + i)
        sim.reset(rng, start=start(rng))
        log: list[np.ndarray] = []
        sim.run(seconds, [Every(1 / sim.cfg.log_hz, lambda s, log=log: log.append(s.poses))])
        poses = np.array(log)
        out += [poses[:, c[k:k + 3]] for c in chains for k in range(len(c) - 2)]
    return np.array(out)


def estimator_runs(train_steps: int, rehearsals: int, seconds: float, stride: int,
                   rng: np.random.Generator,
                   rehearse: Callable[[int, float], np.ndarray] = rehearsal_runs
                   ) -> list[np.ndarray]:
    """What the caging Tail's estimator learns from: the robotarium training runs of `experiment
    retlo-sim` and `rehearsals` passive-Tail caging runs of `seconds` (`rehearse`: of the line
    team, or `team_rehearsal_runs`), each taken at every `stride`-th log step from each phase,
    as 5 noisy replicas (σ 1 mm): one array per (source, phase), in that order (the draws from
    `rng` follow it)."""
    runs = training_runs(ARENA, train_steps, K_T_FACTORS)
    rehearsed = rehearse(rehearsals, seconds)
    return [noisy_replicas(r[:, k::stride], 5, 0.001, rng)
            for r in (runs, rehearsed) for k in range(stride)]
