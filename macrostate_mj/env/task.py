"""The Tail's task on dm_control's lifecycle (`suite.base.Task`: `initialize_episode`,
`before_step`, `after_step`, `get_observation`, `get_reward`, `get_termination`, and its
seeded `random`): what every Tail task shares. The tasks themselves (`ExploreTask`,
`CagingTask`) set the reward and the ending, and register themselves in `TASKS` by name
(`@TASKS.register("explore")`), imported on `TASKS`' first read; `env.suite` builds their
`control.Environment`.

One environment step is one command tick: the agent sets the Tail's destination offset (the same
control SRS perturbs), every robot's controller runs (planner, motion rules, unicycle tracking),
and MuJoCo steps to the next tick. The Tail observes its own pose and its neighbour's over the
last `history` ticks: from the ground truth, or with `observe="camera"` its neighbour through
the overhead camera, imaging noise and tracker (the Tail knows its own pose).
"""

from __future__ import annotations

import collections

import mujoco
import numpy as np
from dm_control import mujoco as dm_mujoco
from dm_control.suite import base
from dm_env import specs

from macrostate_mj.chain.sim import ChainSim
from macrostate_mj.chain.world import World
from macrostate_mj.core.errors import UserError
from macrostate_mj.core.registry import Registry
from macrostate_mj.vision.health import TrackingHealth

OBSERVE = ("truth", "camera")
# The task modules, named rather than scanned (`core.registry`): this package also holds modules
# that are not tasks and need what a task does not (gymnasium, PettingZoo: an optional extra).
TASKS: Registry[type[TailTask]] = Registry(
    "task", [f"macrostate_mj.env.{m}" for m in ("caging", "explore", "localize")])


class TailTask(base.Task):
    """What the Tail sees and may do (see the module docstring); subclasses say what it is
    rewarded for (`get_reward`, abstract here) and when the episode ends."""

    def __init__(self, sim: ChainSim, history: int = 10, observe: str = "truth",
                 random: np.random.RandomState | int | None = None):
        if observe not in OBSERVE:
            raise UserError(f"observe={observe!r}; choose one of {', '.join(OBSERVE)}")
        if history < 1:
            raise UserError(f"history must be at least 1 tick, got {history}")
        super().__init__(random=random)
        self.sim, self.history, self.observe = sim, history, observe
        self.max_offset = sim.cfg.spacing            # the destination moves at most d
        self.camera = None
        self.fault = None
        # Which robot is the agent and which its neighbour: one each here; a team of several
        # Tails (`env.caging.TeamCagingTask`) sets index arrays, and every pose, observation
        # and action gains a leading axis of one row per Tail.
        self.me: int | np.ndarray = -1
        self.seen: int | np.ndarray = -2
        self._tail: collections.deque = collections.deque(maxlen=history)
        self._neighbour: collections.deque = collections.deque(maxlen=history)

    @classmethod
    def create(cls, world: World, data: mujoco.MjData, history: int = 10,
               observe: str = "truth", random: np.random.RandomState | int | None = None
               ) -> TailTask:
        """The task on a simulation of `world` that steps the physics' own `data` (what
        `suite.load` calls: each task builds the simulation it needs)."""
        return cls(ChainSim(world, data=data), history, observe, random)

    def seed(self, random: np.random.RandomState | int | None) -> None:
        """Draw the next episodes from `random` (a RandomState, or its seed): how the
        Gymnasium view passes on `reset(seed=...)`."""
        self._random = (random if isinstance(random, np.random.RandomState)
                        else np.random.RandomState(random))

    def reset_info(self) -> dict:
        """What the Tail knows at the start beyond its observation (Gymnasium's reset info)."""
        return {}

    def step_info(self) -> dict:
        """What a step reports beyond its observation (Gymnasium's step info)."""
        return {"fault": None if self.fault is None else str(self.fault)}

    def tracking_health(self) -> TrackingHealth | None:
        """This episode's tracking health so far (with `observe="camera"`; else None): judge it
        with `.judged(task.sim.cfg)`, as every tracked run is judged."""
        return None if self.camera is None else self.camera.health.report()

    def close(self) -> None:
        """Release the camera's renderer (with `observe="camera"`)."""
        if self.camera is not None:
            self.camera.close()
            self.camera = None

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

    def before_step(self, action: np.ndarray, physics: dm_mujoco.Physics) -> None:
        action = np.asarray(action, np.float64)
        shape = (*np.shape(self.me), 2)
        # a float32 action at the bound (Gymnasium's Box) rounds up by ~1e-8 m: that is inside
        if action.shape != shape or not np.all(np.abs(action) <= self.max_offset * (1 + 1e-6)):
            raise ValueError(f"action {action.tolist()} is outside the action spec: shape "
                             f"{shape} within ±{self.max_offset:g} m")
        self.sim.tail_offset = np.clip(action, -self.max_offset, self.max_offset)
        self.sim.command()

    def after_step(self, physics: dm_mujoco.Physics) -> None:
        self.fault = self.fault or self.sim.monitor.check(physics.data.ptr)
        self._record()

    def action_spec(self, physics: dm_mujoco.Physics) -> specs.BoundedArray:
        b = self.max_offset
        return specs.BoundedArray((*np.shape(self.me), 2), np.float64, -b, b,
                                  name="tail_destination_offset_m")

    def extra_observations(self) -> dict[str, np.ndarray]:
        """What a task lets the Tail observe besides the poses (name -> float array of a fixed
        shape; the spec is read off it)."""
        return {}

    def observation_spec(self, physics: dm_mujoco.Physics) -> collections.OrderedDict:
        shape = (*np.shape(self.me), self.history, 3)
        spec = collections.OrderedDict(
            tail=specs.Array(shape, np.float64, name="tail"),
            neighbour=specs.Array(shape, np.float64, name="neighbour"))
        for name, value in self.extra_observations().items():
            spec[name] = specs.Array(np.shape(value), np.float64, name=name)
        return spec

    def get_observation(self, physics: dm_mujoco.Physics) -> collections.OrderedDict:
        # (history, [tails,] 3) as recorded; (…, history, 3) as observed
        return collections.OrderedDict(
            tail=np.moveaxis(np.array(self._tail), 0, -2),
            neighbour=np.moveaxis(np.array(self._neighbour), 0, -2), **self.extra_observations())

    def get_termination(self, physics: dm_mujoco.Physics) -> float | None:
        """Every task ends (discount 0) when the physics faults."""
        return 0.0 if self.fault is not None else None

    # -- what the Tail knows -----------------------------------------------------------------
    def _record(self) -> None:
        poses = self.sim.poses
        neighbour = poses[self.seen]
        if self.camera is not None:      # a neighbour the tracker misses keeps its last pose
            self.camera.capture(self.sim)
            seen = self.camera.latest[self.seen]
            held = self._neighbour[-1] if self._neighbour else neighbour
            neighbour = np.where(np.all(np.isfinite(seen), axis=-1, keepdims=True), seen, held)
        self._tail.append(poses[self.me].copy())
        self._neighbour.append(np.asarray(neighbour, np.float64).copy())
