"""The chain simulation loop: motion rules at the command rate, poses logged at the log rate.

Lifecycle (dm_control-style names say when things happen):
  `ChainSim(world)`        compile once;
  `reset(rng)`             full MuJoCo reset (warm start included), start poses, planner, log phase;
  `episode(seconds, hooks)` each hook's `initialize_episode`, then `run`, then each hook's
                           `finalize_episode` (the `Hook` protocol);
  `run(seconds, hooks)`    step physics in C between events (`mj_step(..., nstep=k)`), firing
                           the controller and each hook's `on_tick` (logger, renderer, tracker)
                           on its tick, and check the physics' health after every stretch.
Event times are whole physics steps (a scenario whose rates do not divide into whole steps is
rejected when it is made: `scenarios.steps_per_tick`), so runs are bit-identical for the same
seed. A fault (NaN, tip, lift, escape) is pinned to the physics step where it first appears: the
stretch is replayed step by step from its saved state, which on one machine reproduces it
exactly.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Protocol

import mujoco
import numpy as np

from macrostate_mj.chain.health import DIVERGED, PhysicsError, PhysicsFault, PhysicsMonitor
from macrostate_mj.chain.motion import (
    avoidance_velocities,
    chain_velocities,
    path_blocked,
    steer_around,
    unicycle_commands,
    wheel_commands,
)
from macrostate_mj.chain.planners import Planner
from macrostate_mj.chain.world import World, check_start, place_chain
from macrostate_mj.core.checks import check_seed
from macrostate_mj.core.errors import UserError


class Hook(Protocol):
    """A participant of an episode. The names say when each is called (dm_control's lifecycle):
    `initialize_episode` once, after `reset` and before the first tick; `on_tick` on each of the
    hook's ticks, every `period` s from `phase` after the episode starts (or, for a hook with a
    `tick_time(count)` method, at the times it gives: the camera's jittered frames);
    `finalize_episode` once at the end, `keep=False` when the run was interrupted (partial
    outputs are removed) and True otherwise, a physics failure included (what was simulated up
    to it is kept)."""

    period: float
    phase: float

    def initialize_episode(self, sim: ChainSim) -> None: ...

    def on_tick(self, sim: ChainSim) -> None: ...

    def finalize_episode(self, sim: ChainSim, keep: bool) -> None: ...


@dataclass
class Every:
    """A plain callable as a hook: `fn(sim)` every `period` s from `phase`."""

    period: float
    fn: Callable[[ChainSim], None]
    phase: float = 0.0

    def initialize_episode(self, sim: ChainSim) -> None:
        pass

    def on_tick(self, sim: ChainSim) -> None:
        self.fn(sim)

    def finalize_episode(self, sim: ChainSim, keep: bool) -> None:
        pass


class _Ticks:
    """When a hook is due: tick times rounded to whole physics steps and computed from the tick
    count (no drift). A hook with `tick_time(count)` (s after its phase) ticks irregularly:
    the camera's frames when their timing jitters."""

    def __init__(self, hook: Hook, t0: float, dt: float):
        self.hook, self.dt = hook, dt
        self.origin, self.count = t0 + hook.phase, 0
        self.when = getattr(hook, "tick_time", None)
        self.next_step = int(round(self._time(0) / dt))

    def _time(self, count: int) -> float:
        return self.origin + (count * self.hook.period if self.when is None
                              else self.when(count))

    def fire_if_due(self, sim: ChainSim, step: int) -> None:
        if step >= self.next_step:
            self.hook.on_tick(sim)
            self.count += 1
            self.next_step = int(round(self._time(self.count) / self.dt))


class Mission(Protocol):
    """Rewrites the chain's reference velocities (n, 2) in place each command tick."""

    def reset(self) -> None: ...

    def adjust(self, t: float, poses: np.ndarray, vel: np.ndarray, d: float, k_f: float,
               head_speed: float) -> None: ...


class Tracker(Protocol):
    """What the chain's hooks may read of a camera tracker (`vision.camera_chain.CameraChain`):
    each robot's latest tracked pose (n, 3), NaN before its first detection."""

    @property
    def latest(self) -> np.ndarray: ...


@dataclass
class PoseLog:
    """Poses at log ticks: times (T,), poses (T, n, 3), Head waypoint (T, 2) or NaN, and, with
    a `tracker` (anything with `latest` (n, 3), `latest_time` (n,), `latest_truth` (n, 3) and
    `detected` (n,)), its latest output and the true poses at the moment it was seen."""

    names: list[str]
    tracker: object | None = None
    times: list[float] = field(default_factory=list)
    poses: list[np.ndarray] = field(default_factory=list)
    waypoints: list[np.ndarray] = field(default_factory=list)
    tracked: list[np.ndarray] = field(default_factory=list)
    tracked_time: list[np.ndarray] = field(default_factory=list)
    tracked_truth: list[np.ndarray] = field(default_factory=list)
    detected: list[np.ndarray] = field(default_factory=list)

    def append(self, sim: ChainSim) -> None:
        self.times.append(sim.time)
        self.poses.append(sim.poses)
        wp = sim.planner.target
        self.waypoints.append(np.array(wp, float) if wp is not None else np.full(2, np.nan))
        if self.tracker is not None:
            self.tracked.append(self.tracker.latest.copy())
            self.tracked_time.append(self.tracker.latest_time.copy())
            self.tracked_truth.append(self.tracker.latest_truth.copy())
            self.detected.append(self.tracker.detected.copy())

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        n = len(self.names)
        return (np.asarray(self.times), np.asarray(self.poses).reshape(-1, n, 3),
                np.asarray(self.waypoints).reshape(-1, 2))

    def tracked_arrays(self) -> dict[str, np.ndarray] | None:
        """{"tracked": (T, n, 3), "tracked_time": (T, n), "tracked_truth": (T, n, 3),
        "detected": (T, n)} or None."""
        if self.tracker is None:
            return None
        n = len(self.names)
        return {"tracked": np.asarray(self.tracked).reshape(-1, n, 3),
                "tracked_time": np.asarray(self.tracked_time).reshape(-1, n),
                "tracked_truth": np.asarray(self.tracked_truth).reshape(-1, n, 3),
                "detected": np.asarray(self.detected).reshape(-1, n)}


class ChainSim:
    """Runs one chain world; owns its MjData, planner and the controller's state."""

    def __init__(self, world: World, k_t: float | None = None, planner: Planner | None = None,
                 data: mujoco.MjData | None = None, mission: Mission | None = None):
        self.world = world
        self.cfg = world.scenario
        self.model = world.model
        # `data`: someone else's MjData of this model (dm_control's Physics, in `env`)
        self.data = mujoco.MjData(self.model) if data is None else data
        self.planner = planner or self.cfg.planner.build(self.cfg.arena, self.cfg.wall_margin,
                                                         self.cfg.reach_radius, self.cfg.obstacles)
        self.k_t = self.cfg.k_t if k_t is None else k_t
        if not (isinstance(self.k_t, int | float) and math.isfinite(self.k_t) and self.k_t > 0):
            raise UserError(f"k_t must be a positive finite gain, got {self.k_t!r}", "k_t")
        self.rng = np.random.default_rng(0)
        self.log_phase = 0.0
        # Displacement of the Tail's destination (m), set by a data-collection policy (SRS).
        self.tail_offset = np.zeros(2)
        # A mission (e.g. `chain.caging_mission.CagingMission`) that rewrites the reference
        # velocities; with one, the Head is driven by its velocity, not by the planner's
        # (v, omega).
        self.mission = mission
        self.n = len(world.names)
        self._body = world.body
        # Speed caps and reversing per robot: the Head drives at most head_speed, forward only.
        self._v_max = np.array([self.cfg.head_speed] + [self.cfg.chain_speed] * (self.n - 1))
        self._reverse = np.array([False] + [self.cfg.allow_reverse] * (self.n - 1))
        self._turn_speed = np.array([self.cfg.head_turn_speed] + [0.0] * (self.n - 1))
        self.monitor = PhysicsMonitor(world)
        # Health checks at least this often (physics steps); events bound the stretches too.
        self.check_steps = 10**9
        self._wheel_gain: np.ndarray | None = None     # (n, 2) per episode (`wheel_spread`)
        self._ctrlrange = self.model.actuator_ctrlrange.copy()
        self._state_spec = mujoco.mjtState.mjSTATE_INTEGRATION
        self._saved = np.empty(mujoco.mj_stateSize(self.model, self._state_spec))

    def _spread_wheels(self, rng: np.random.Generator) -> None:
        """Each wheel's effective radius this episode (`wheel_spread`), as the speed factor its
        commanded rate turns into: drawn from a child of the reset stream only when the spread
        is above zero, so a lab without it keeps every draw. The wheels' shapes stay as built:
        a wheel of another size would tilt the robot, which then creeps while parked."""
        self._wheel_gain = None
        self.model.actuator_ctrlrange[:] = self._ctrlrange
        spread = self.cfg.wheel_spread
        if spread > 0:
            child = np.random.default_rng(rng.integers(2**63))
            draws = np.clip(child.standard_normal(2 * self.n), -3, 3)
            self._wheel_gain = (1 + spread * draws).reshape(self.n, 2)
            # a larger wheel is faster at the motor's top rate too
            for side, ids in enumerate((self.world.ctrl_left, self.world.ctrl_right)):
                self.model.actuator_ctrlrange[ids] *= self._wheel_gain[:, side, None]

    # -- lifecycle ---------------------------------------------------------------------------
    def reset(self, rng: np.random.Generator | int, start: np.ndarray | None = None) -> None:
        """Full reset: a fresh state (warm start included), start poses drawn from `rng` (a
        Generator, or a seed for one) unless given."""
        if not isinstance(rng, np.random.Generator):
            check_seed(rng, "rng", also="a numpy Generator or ")
            rng = np.random.default_rng(rng)
        if start is not None:
            start = check_start(self.cfg, self.n, start)
        self.rng = rng
        mujoco.mj_resetData(self.model, self.data)
        self.monitor.reset()
        self.tail_offset = np.zeros(2)
        if self.mission is not None:
            self.mission.reset()
        start = place_chain(self.cfg, self.n, rng) if start is None else start
        self._spread_wheels(rng)
        for adr, (x, y, th) in zip(self.world.qpos_adr, start, strict=True):
            self.data.qpos[adr:adr + 3] = [x, y, self.model.qpos0[adr + 2]]
            self.data.qpos[adr + 3:adr + 7] = [np.cos(th / 2), 0, 0, np.sin(th / 2)]
        mujoco.mj_forward(self.model, self.data)
        # The 2 Hz log is not synchronized with the 4 Hz commands (seed §2.6.2.2).
        self.log_phase = float(rng.uniform(0, 1 / self.cfg.log_hz)) \
            if self.cfg.log_hz != self.cfg.command_hz else 0.0
        self.planner.reset(self.poses[0], rng)

    @property
    def time(self) -> float:
        return float(self.data.time)

    @property
    def poses(self) -> np.ndarray:
        """(n, 3) x, y, theta in the world frame; heading from the body frame (not the mesh)."""
        xmat = self.data.xmat[self._body]
        theta = np.arctan2(xmat[:, 3], xmat[:, 0])
        return np.column_stack([self.data.xpos[self._body, :2], theta])

    # -- control ------------------------------------------------------------------------------
    def command(self) -> None:
        """One control tick: planner, motion rules, unicycle tracking, wheel speeds."""
        cfg, w = self.cfg, self.world
        poses = self.poses
        self.planner.update(poses[0], self.time, self.rng)
        vel = self.reference_velocities(poses)
        if self.mission is not None:
            self.mission.adjust(self.time, poses, vel, cfg.spacing, cfg.k_f, cfg.head_speed)
        v, omega = unicycle_commands(vel, poses[:, 2], cfg.k_omega, self._v_max, self._reverse,
                                     turn_speed=self._turn_speed)
        if self.planner.twist is not None and self.mission is None:
            v[0], omega[0] = self.planner.twist
            if path_blocked(poses[:, :2], 0, poses[0, 2], cfg.avoid_radius):
                v[0] = 0.0     # a Head driven in (v, omega) waits rather than ram a robot
        left, right = wheel_commands(v, omega, w.wheel_radius, w.track, w.max_wheel_speed)
        if self._wheel_gain is not None:
            left, right = left * self._wheel_gain[:, 0], right * self._wheel_gain[:, 1]
        self.data.ctrl[w.ctrl_left] = left
        self.data.ctrl[w.ctrl_right] = right

    def reference_velocities(self, poses: np.ndarray) -> np.ndarray:
        """The motion rules' holonomic velocities (n, 2), before any mission: what a team of
        another shape (`chain.team.BranchedSim`) redefines."""
        cfg = self.cfg
        vel = self.kept_apart(poses[:, :2], chain_velocities(
            poses[:, :2], self.planner.target, cfg.spacing, cfg.k_f, self.k_t,
            followers=cfg.followers))
        # The Tail rule is k_t |p_F - p_T| (D - p_T) with D its destination at distance d from
        # its neighbour; a policy moves D by `tail_offset` (seed §3.3).
        gap = np.linalg.norm(poses[-2, :2] - poses[-1, :2])
        vel[-1] += self.k_t * gap * self.tail_offset
        return vel

    def kept_apart(self, positions: np.ndarray, vel: np.ndarray) -> np.ndarray:
        """`vel` (modified) plus the robots' mutual repulsion, then steered round obstacles:
        what every team shape adds to its motion rules."""
        cfg = self.cfg
        vel += avoidance_velocities(positions, cfg.avoid_radius, cfg.avoid_gain)
        if cfg.obstacles:
            vel = steer_around(positions, vel, cfg.obstacles, cfg.avoid_radius, cfg.avoid_gain)
        return vel

    # -- loop ---------------------------------------------------------------------------------
    def episode(self, seconds: float, hooks: Sequence[Hook],
                progress: Callable[[float], None] | None = None) -> None:
        """`run` inside the hooks' lifecycle: initialize each, run, finalize each (see `Hook`);
        a `PhysicsError` is raised again once every hook has kept what it has."""
        for hook in hooks:
            hook.initialize_episode(self)
        try:
            self.run(seconds, hooks, progress)
        except PhysicsError:
            self._finalize(hooks, keep=True)
            raise
        except BaseException:
            self._finalize(hooks, keep=False)
            raise
        self._finalize(hooks, keep=True)

    def _finalize(self, hooks: Sequence[Hook], keep: bool) -> None:
        for hook in hooks:
            hook.finalize_episode(self, keep)

    def run(self, seconds: float, hooks: Sequence[Hook],
            progress: Callable[[float], None] | None = None) -> None:
        """Advance `seconds` of simulated time, firing the controller first, then each hook's
        `on_tick` when due (no lifecycle calls: see `episode`)."""
        if not (isinstance(seconds, int | float) and math.isfinite(seconds) and seconds >= 0):
            raise UserError(f"seconds must be a finite non-negative number, got {seconds!r}")
        dt = self.model.opt.timestep
        controller = Every(1 / self.cfg.command_hz, lambda s: s.command())
        events = [_Ticks(h, self.time, dt) for h in (controller, *hooks)]
        step = int(round(self.time / dt))
        end = step + int(round(seconds / dt))
        m, d = self.model, self.data
        while step < end:
            for ev in events:
                ev.fire_if_due(self, step)
            nxt = min(end, step + self.check_steps, *(ev.next_step for ev in events))
            mujoco.mj_getState(m, d, self._saved, self._state_spec)
            mujoco.mj_step(m, d, nstep=nxt - step)
            fault = self.monitor.check(d, nxt * dt)
            if fault is not None:
                raise PhysicsError(self._replay_to_fault(step, nxt) or fault)
            step = nxt
            if progress is not None:
                progress(self.time)
        self.monitor.record_warnings(d)

    def _replay_to_fault(self, start: int, end: int) -> PhysicsFault | None:
        """Rewind to the stretch's start and step one by one to the first unhealthy step."""
        m, d = self.model, self.data
        mujoco.mj_setState(m, d, self._saved, self._state_spec)
        for w in DIVERGED:
            d.warning[w].number = 0          # they were 0 when the stretch began
        for k in range(start + 1, end + 1):
            mujoco.mj_step(m, d)
            fault = self.monitor.check(d, k * m.opt.timestep)
            if fault is not None:
                self.monitor.record_warnings(d)
                return fault
        return None


def simulate_poses(world: World, seconds: float, seed: int,
                   extra_hooks: list[Hook] | None = None,
                   progress: Callable[[float], None] | None = None) -> tuple[ChainSim, PoseLog]:
    """Reset with `seed` and run, logging poses at the scenario's log rate."""
    sim = ChainSim(world)
    sim.reset(np.random.default_rng(seed))
    log = PoseLog(world.names)
    hooks = [Every(1 / world.scenario.log_hz, log.append, sim.log_phase), *(extra_hooks or [])]
    sim.episode(seconds, hooks, progress)
    return sim, log


BREAK_SPACINGS = 2.5     # a neighbour gap over this many spacings d: the chain has come apart


def chain_broken(sim: ChainSim) -> bool:
    """A neighbour gap over `BREAK_SPACINGS` × d: the chain has come apart (what ends a Tail
    environment's episode, and what the learned Tail's shield keeps it from)."""
    gaps = np.linalg.norm(np.diff(sim.poses[:, :2], axis=0), axis=1)
    return bool(gaps.max() > BREAK_SPACINGS * sim.cfg.spacing)
