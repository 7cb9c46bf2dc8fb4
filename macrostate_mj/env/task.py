"""The Tail's task on dm_control's lifecycle (`suite.base.Task`: `initialize_episode`,
`before_step`, `after_step`, `get_observation`, `get_reward`, `get_termination`, and its
seeded `random`), and the `control.Environment` that runs it.

One environment step is one command tick: the agent sets the Tail's destination offset (the same
control SRS perturbs), every robot's controller runs (planner, motion rules, unicycle tracking),
and MuJoCo steps to the next tick. The Tail observes its own pose and its neighbour's over the
last `history` ticks: from the ground truth, or with `observe="camera"` its neighbour through
the overhead camera, imaging noise and tracker (the Tail knows its own pose).

Tasks (`TASKS`): `explore` rewards the change of the neighbour's position in the Tail's frame
from one tick to the next (m): a plain exploration signal, not chapter 3's novelty index. An
episode ends (discount 0) when the chain breaks (a neighbour gap over `BREAK_SPACINGS` × d) or
the physics faults; it is truncated at `time_limit`.
"""

from __future__ import annotations

import collections

import numpy as np
from dm_control import mujoco as dm_mujoco
from dm_control.mujoco import wrapper
from dm_control.rl import control
from dm_control.suite import base
from dm_env import specs

from macrostate_mj.chain.caging import CagingConfig, CagingMission
from macrostate_mj.chain.scenarios import scenario_for
from macrostate_mj.chain.sim import ChainSim
from macrostate_mj.chain.world import build_world, validate_chain
from macrostate_mj.core.errors import UserError

TASKS = ("explore", "caging")
OBSERVE = ("truth", "camera")
BREAK_SPACINGS = 2.5


class TailTask(base.Task):
    """What the Tail sees, may do and is rewarded for (see the module docstring)."""

    def __init__(self, sim: ChainSim, task: str = "explore", history: int = 10,
                 observe: str = "truth", random: np.random.RandomState | int | None = None):
        if task not in TASKS:
            raise UserError(f"unknown task {task!r}; choose one of {', '.join(TASKS)}")
        if observe not in OBSERVE:
            raise UserError(f"observe={observe!r}; choose one of {', '.join(OBSERVE)}")
        if history < 1:
            raise UserError(f"history must be at least 1 tick, got {history}")
        super().__init__(random=random)
        self.sim, self.task, self.history, self.observe = sim, task, history, observe
        self.max_offset = sim.cfg.spacing            # the destination moves at most d
        self.camera = None
        self.fault = None
        self._tail: collections.deque = collections.deque(maxlen=history)
        self._neighbour: collections.deque = collections.deque(maxlen=history)
        self._relative = np.zeros(2)

    # -- dm_control lifecycle ----------------------------------------------------------------
    def initialize_episode(self, physics: dm_mujoco.Physics) -> None:
        self._start_episode(np.random.default_rng(self.random.randint(2**31)))

    def _start_episode(self, rng: np.random.Generator, start: np.ndarray | None = None) -> None:
        """Reset the team (at `start`, or placed by the scenario) and the Tail's history."""
        self.sim.reset(rng, start)
        self.fault = None
        if self.observe == "camera":
            from macrostate_mj.vision.camera_chain import CameraChain

            if self.camera is None:
                self.camera = CameraChain(self.sim)
            self.camera.start(np.random.default_rng(self.random.randint(2**31)))
        self._tail.clear()
        self._neighbour.clear()
        self._record()
        while len(self._tail) < self.history:       # a still history before the first tick
            self._tail.append(self._tail[-1])
            self._neighbour.append(self._neighbour[-1])
        self._relative = self._relative_position()

    def before_step(self, action: np.ndarray, physics: dm_mujoco.Physics) -> None:
        action = np.asarray(action, np.float64)
        # a float32 action at the bound (Gymnasium's Box) rounds up by ~1e-8 m: that is inside
        if action.shape != (2,) or not np.all(np.abs(action) <= self.max_offset * (1 + 1e-6)):
            raise ValueError(f"action {action.tolist()} is outside the action spec: a 2-vector "
                             f"within ±{self.max_offset:g} m")
        self.sim.tail_offset = np.clip(action, -self.max_offset, self.max_offset)
        self.sim.command()

    def after_step(self, physics: dm_mujoco.Physics) -> None:
        self.fault = self.fault or self.sim.monitor.check(physics.data.ptr)
        self._record()

    def action_spec(self, physics: dm_mujoco.Physics) -> specs.BoundedArray:
        b = self.max_offset
        return specs.BoundedArray((2,), np.float64, -b, b, name="tail_destination_offset_m")

    def observation_spec(self, physics: dm_mujoco.Physics) -> collections.OrderedDict:
        shape = (self.history, 3)
        return collections.OrderedDict(
            tail=specs.Array(shape, np.float64, name="tail"),
            neighbour=specs.Array(shape, np.float64, name="neighbour"))

    def get_observation(self, physics: dm_mujoco.Physics) -> collections.OrderedDict:
        return collections.OrderedDict(tail=np.array(self._tail), neighbour=np.array(
            self._neighbour))

    def get_reward(self, physics: dm_mujoco.Physics) -> float:
        now = self._relative_position()
        reward, self._relative = float(np.linalg.norm(now - self._relative)), now
        return reward

    def get_termination(self, physics: dm_mujoco.Physics) -> float | None:
        gaps = np.linalg.norm(np.diff(self.sim.poses[:, :2], axis=0), axis=1)
        if self.fault is not None or gaps.max() > BREAK_SPACINGS * self.sim.cfg.spacing:
            return 0.0
        return None

    # -- what the Tail knows -----------------------------------------------------------------
    def _record(self) -> None:
        poses = self.sim.poses
        neighbour = poses[-2]
        if self.camera is not None:
            self.camera.capture(self.sim)
            seen = self.camera.latest[-2]
            neighbour = seen if np.all(np.isfinite(seen)) else (
                self._neighbour[-1] if self._neighbour else neighbour)
        self._tail.append(poses[-1].copy())
        self._neighbour.append(np.asarray(neighbour, np.float64).copy())

    def _relative_position(self) -> np.ndarray:
        tail, neighbour = self._tail[-1], self._neighbour[-1]
        d = neighbour[:2] - tail[:2]
        c, s = np.cos(tail[2]), np.sin(tail[2])
        return np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1]])


def make_environment(scenario: str = "lab", robots: int = 3, task: str = "explore",
                     history: int = 10, observe: str = "truth", time_limit: float = 60.0,
                     random: np.random.RandomState | int | None = None,
                     caging: CagingConfig | None = None,
                     ) -> tuple[control.Environment, TailTask]:
    """A dm_control `Environment` of the Tail's task (and the task, for its simulation);
    `caging` configures the caging task's object (default `CagingConfig()`)."""
    if task not in TASKS:
        raise UserError(f"unknown task {task!r}; choose one of {', '.join(TASKS)}")
    cfg = scenario_for(scenario)
    validate_chain(cfg, robots, time_limit)
    world = build_world(cfg, robots)
    physics = dm_mujoco.Physics.from_model(wrapper.MjModel(world.model))
    if task == "caging":
        from macrostate_mj.env.caging import CagingTask

        caging = caging or CagingConfig()
        caging.validate(cfg.arena)
        sim = ChainSim(world, data=physics.data.ptr, mission=CagingMission(caging))
        tail: TailTask = CagingTask(sim, caging, history, observe, random)
    else:
        sim = ChainSim(world, data=physics.data.ptr)
        tail = TailTask(sim, task, history, observe, random)
    env = control.Environment(physics, tail, time_limit=time_limit,
                              control_timestep=1 / cfg.command_hz)
    return env, tail

