"""Simulated chains of the robotarium scenario: training treatments (§2.5.2.1) and test runs.

A run is one continuous pose log at the scenario's log rate (one step = one 30 Hz tick). Every
run starts from a straight chain placed so that the Head's *nominal* path (its (v, ω) schedule
integrated exactly) and the start chain stay inside the walls' margin, with the most room to
spare; the logged run is then checked against the walls. Why not restart when the Head nears a
wall: a restart adds a start-up transient and the planner's on-the-spot wall turns are not one
of the five preset velocities, so one clean 800-step run per treatment is closer to §2.5.2.1.
A run that cannot fit (the 1,600-step straight test: 1.6 m of travel plus a 0.4 m chain in a
1.2 m arena) runs on the same floor with the walls taken out, and says so.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from macrostate_mj.chain.planners import ROBOTARIUM_HEAD_PRESETS
from macrostate_mj.chain.scenario import ScenarioConfig
from macrostate_mj.chain.sim import ChainSim, Every, PoseLog
from macrostate_mj.chain.world import World, build_world
from macrostate_mj.core.errors import UserError

K_T_FACTORS = (0.25, 0.5, 1.0, 2.0)   # × the scenario's k_t: a looser and a stiffer Tail
ROBOT_RADIUS = 0.015                   # GRITSBot-like body (seed §2.5.2: diameter 0.03)


@dataclass
class PresetSchedule:
    """Head planner driving preset `presets[i]` from step `start` on, for each (start, i) of
    `schedule` (sorted by start). No wall turns: runs are placed so that none is needed."""

    schedule: tuple[tuple[int, int], ...]
    log_hz: float
    presets: tuple[tuple[float, float], ...] = ROBOTARIUM_HEAD_PRESETS
    target: np.ndarray | None = None
    twist: tuple[float, float] | None = None

    def reset(self, head_pose: np.ndarray, rng: np.random.Generator) -> None:
        self.update(head_pose, 0.0, rng)

    def update(self, head_pose: np.ndarray, t: float, rng: np.random.Generator) -> None:
        step = t * self.log_hz + 1e-6
        current = [i for start, i in self.schedule if start <= step]
        self.twist = self.presets[current[-1] if current else self.schedule[0][1]]


def twists_of(schedule: tuple[tuple[int, int], ...], steps: int,
              presets: tuple[tuple[float, float], ...] = ROBOTARIUM_HEAD_PRESETS) -> np.ndarray:
    """(steps, 2) commanded (v, ω) per step of a schedule."""
    idx = np.full(steps, schedule[0][1])
    for start, i in schedule:
        idx[start:] = i
    return np.asarray(presets, np.float64)[idx]


def nominal_path(pose: np.ndarray, twists: np.ndarray, dt: float) -> np.ndarray:
    """(S + 1, 3) poses of a unicycle driving `twists` (S, 2) from `pose`, integrated exactly
    (arcs, not Euler steps)."""
    out = [np.asarray(pose, np.float64)]
    for v, w in twists:
        x, y, th = out[-1]
        if abs(w) < 1e-12:
            nxt = (x + v * dt * np.cos(th), y + v * dt * np.sin(th), th)
        else:
            r = v / w
            nxt = (x + r * (np.sin(th + w * dt) - np.sin(th)),
                   y - r * (np.cos(th + w * dt) - np.cos(th)), th + w * dt)
        out.append(np.array(nxt))
    return np.array(out)


def straight_chain(head: np.ndarray, n: int, spacing: float) -> np.ndarray:
    """(n, 3) start poses in pose-log order (H, F1, ..., T): a straight chain behind `head`."""
    back = np.arange(n)[:, None] * spacing * np.array([np.cos(head[2]), np.sin(head[2])])
    return np.column_stack([head[:2] - back, np.full(n, head[2])])


def fit_start(cfg: ScenarioConfig, n: int, twists: np.ndarray, n_headings: int = 72
              ) -> tuple[np.ndarray, float]:
    """Start chain (n, 3) whose nominal Head path and start chain are centred in the arena, at
    the start heading (of `n_headings`) with the most room to the walls' margin; also that
    room (m, negative when the run cannot fit)."""
    half = np.array(cfg.arena) / 2 - cfg.wall_margin
    best: tuple[float, np.ndarray] | None = None
    for phi in np.arange(n_headings) * 2 * np.pi / n_headings:
        path = nominal_path(np.array([0.0, 0.0, phi]), twists, 1 / cfg.log_hz)
        pts = np.vstack([path[:, :2], straight_chain(path[0], n, cfg.spacing)[:, :2]])
        lo, hi = pts.min(0), pts.max(0)
        room = float(np.min(half - (hi - lo) / 2))
        if best is None or room > best[0] + 1e-9:
            shift = -(hi + lo) / 2
            best = (room, straight_chain(path[0] + np.array([*shift, 0.0]), n, cfg.spacing))
    assert best is not None
    return best[1], best[0]


def run_chain(world: World, start: np.ndarray, steps: int, k_t: float,
              schedule: tuple[tuple[int, int], ...], walls: bool = True) -> np.ndarray:
    """Simulate one run: (steps, n, 3) logged poses (H first), checked to stay off the walls."""
    cfg = world.scenario
    sim = ChainSim(world, k_t=k_t, planner=PresetSchedule(schedule, cfg.log_hz))
    sim.reset(np.random.default_rng(0), start=start)  # the rng draws nothing at 30 = 30 Hz
    log = PoseLog(world.names)
    sim.run(steps / cfg.log_hz, [Every(1 / cfg.log_hz, log.append, sim.log_phase)])
    poses = log.arrays()[1][:steps]
    if len(poses) != steps:
        raise RuntimeError(f"logged {len(poses)} steps, expected {steps}")
    limit = np.array(cfg.arena) / 2 - ROBOT_RADIUS - 0.005
    if walls and np.any(np.abs(poses[..., :2]) > limit):
        raise RuntimeError("a robot reached a wall; the start placement is wrong")
    return poses


@dataclass(frozen=True)
class Treatment:
    preset: int
    k_t: float


def treatments(cfg: ScenarioConfig, k_t_factors: tuple[float, ...] = K_T_FACTORS
               ) -> list[Treatment]:
    """The 20 treatments of §2.5.2.1: five Head velocities × four k_t."""
    return [Treatment(p, cfg.k_t * f) for p in range(len(ROBOTARIUM_HEAD_PRESETS))
            for f in k_t_factors]


def training_runs(cfg: ScenarioConfig, steps: int, k_t_factors: tuple[float, ...] = K_T_FACTORS,
                  progress: Callable[[int, int], None] | None = None) -> np.ndarray:
    """Clean 3-robot runs, one per treatment: (20, steps, 3, 3). Deterministic (no draws)."""
    world = build_world(cfg, 3)
    runs = []
    todo = treatments(cfg, k_t_factors)
    for i, tr in enumerate(todo):
        sched = ((0, tr.preset),)
        start, room = fit_start(cfg, 3, twists_of(sched, steps))
        if room < 0:
            raise UserError(f"a {steps}-step run of Head preset {tr.preset} does not fit the "
                            f"{cfg.name} arena; use fewer --train-steps")
        runs.append(run_chain(world, start, steps, tr.k_t, sched))
        if progress:
            progress(i + 1, len(todo))
    return np.stack(runs)


def noisy_replicas(runs: np.ndarray, replicas: int, sigma: float, rng: np.random.Generator
                   ) -> np.ndarray:
    """(runs, replicas, ...) copies of every run with N(0, σ²) added to each datum (x, y, θ)."""
    rep = np.repeat(runs[:, None], replicas, axis=1)
    return rep + rng.normal(0.0, sigma, rep.shape)
