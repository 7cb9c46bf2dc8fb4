"""The Gymnasium view of a `suite` task: spaces from the dm_control specs, Gymnasium seeding,
and the overhead camera as `render_mode="rgb_array"`.

A wrapper of our own rather than shimmy's `DmControlCompatibilityV0`: shimmy renders through
dm_control's own cameras (and needs imageio), registers the whole dm_control suite when imported,
and seeds the task by replacing its RandomState; we seed through `TailTask.seed`.
"""

from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np
from dm_control.rl import control
from gymnasium import spaces

from macrostate_mj.env.suite import load
from macrostate_mj.env.task import TailTask
from macrostate_mj.env.view import OverheadView


class TailEnv(OverheadView, gymnasium.Env):
    """The Tail as an agent (see `macrostate_mj.env.task`): Dict observation of its own and
    its neighbour's (history, 3) poses (x, y m; θ rad), a 2-D destination offset as action.
    `environment` is the dm_control environment it wraps, `task` its task (`task.sim` the
    simulation)."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 4}

    def __init__(self, task: str = "explore", scenario: str = "lab", robots: int = 3,
                 history: int = 10, observe: str = "truth", time_limit: float = 60.0,
                 render_mode: str | None = None, **options: Any):
        if render_mode not in (None, "rgb_array"):
            raise gymnasium.error.Error(f"render_mode {render_mode!r}; only 'rgb_array' or None")
        self.render_mode = render_mode
        self.environment: control.Environment = load(task, scenario, robots, history, observe,
                                                     time_limit, **options)
        self.metadata = {**self.metadata, "render_fps": self.task.sim.cfg.command_hz}
        spec = self.environment.action_spec()
        self.action_space = spaces.Box(np.broadcast_to(spec.minimum, spec.shape).astype(np.float32),
                                       np.broadcast_to(spec.maximum, spec.shape).astype(np.float32),
                                       dtype=np.float32)
        hx, hy = np.array(self.task.sim.cfg.arena) / 2      # walls bound every pose
        low, high = np.array([-hx, -hy, -np.pi]), np.array([hx, hy, np.pi])
        self.observation_space = spaces.Dict({
            name: spaces.Box(np.broadcast_to(low, s.shape), np.broadcast_to(high, s.shape),
                             dtype=np.float64)
            for name, s in self.environment.observation_spec().items()})
        self._renderer = None

    @property
    def task(self) -> TailTask:
        return self.environment.task

    def reset(self, *, seed: int | None = None, options: dict | None = None
              ) -> tuple[dict, dict]:
        super().reset(seed=seed)
        self.task.seed(int(self.np_random.integers(2**31)))
        step = self.environment.reset()
        return self._obs(step.observation), self.task.reset_info()

    def step(self, action: Any) -> tuple[dict, float, bool, bool, dict]:
        action = np.asarray(action, np.float64)
        if not self.action_space.contains(action.astype(np.float32)):
            raise gymnasium.error.InvalidAction(
                f"action {action.tolist()} is outside {self.action_space}")
        step = self.environment.step(action)
        terminated = step.last() and step.discount == 0.0
        truncated = step.last() and not terminated
        return (self._obs(step.observation), float(step.reward), terminated, truncated,
                self.task.step_info())

    @staticmethod
    def _obs(observation: dict) -> dict:
        return {k: np.asarray(v, np.float64) for k, v in observation.items()}
