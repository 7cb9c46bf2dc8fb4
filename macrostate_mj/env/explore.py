"""The `explore` task: reward the change of the neighbour's position in the Tail's frame from one
tick to the next (m): a plain exploration signal, not chapter 3's novelty index. An episode ends
(discount 0) when the chain breaks (a neighbour gap over `BREAK_SPACINGS` × d) or the physics
faults; it is truncated at the time limit.
"""

from __future__ import annotations

import numpy as np
from dm_control import mujoco as dm_mujoco

from macrostate_mj.chain.sim import chain_broken
from macrostate_mj.env.task import TASKS, TailTask


@TASKS.register("explore")
class ExploreTask(TailTask):
    """See the module docstring."""

    _relative = np.zeros(2)     # the neighbour in the Tail's frame at the last tick

    def initialize_episode(self, physics: dm_mujoco.Physics) -> None:
        super().initialize_episode(physics)
        self._relative = self._relative_position()

    def get_reward(self, physics: dm_mujoco.Physics) -> float:
        now = self._relative_position()
        reward, self._relative = float(np.linalg.norm(now - self._relative)), now
        return reward

    def get_termination(self, physics: dm_mujoco.Physics) -> float | None:
        return 0.0 if chain_broken(self.sim) else super().get_termination(physics)

    def _relative_position(self) -> np.ndarray:
        tail, neighbour = self._tail[-1], self._neighbour[-1]
        d = neighbour[:2] - tail[:2]
        c, s = np.cos(tail[2]), np.sin(tail[2])
        return np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1]])
