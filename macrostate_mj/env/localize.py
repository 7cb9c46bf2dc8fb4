"""The `localize` task (§5.2): the Tail carries a frozen estimator of its chain and learns to
move so that the estimator localizes the Head well, wherever the Head leads.

The estimator runs live as chapter 2's Tail runs it (`estimators.retlo.online.OnlineChain`: every
pose true from τ over the first ℓ log steps, the window the model reads, as the first ℓ steps of
a ThymioLoc instance are known; then only the Tail's own position and its neighbour's, one log
step at a time).
This module does not import it (the environments and the estimators are sibling layers); the
task takes any object of the `Localizer` shape, and `macrostate_mj.env.estimated` builds the one
behind `LocalizeTail-v0` from a checkpoint.

Action: the Tail's destination offset, as in `explore` (the control SRS perturbs); the Head's
planner is untouched, so the Tail cannot make the task easy by steering the Head. Observation:
the Tail's and its neighbour's poses, and `estimate`: the latest Head estimate relative to the
Tail (world axes, m) and 1, or zeros while it is the shared truth; with an estimator that gives
uncertainty (a `Localizer` whose `head_cov` is not None), also `estimate_cov`: that estimate's
covariance (Σxx, Σxy, Σyy, m²), zeros before the first estimate and where the estimate is the
shared truth. Reward: minus the distance (m) between
the estimator's latest Head estimate and where the Head truly was at that estimate's step, on
every step with an estimate; 0 before the first (no shaping). The episode ends (discount 0)
when the chain breaks or the physics faults, as in `explore`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol

import mujoco
import numpy as np
from dm_control import mujoco as dm_mujoco

from macrostate_mj.chain.sim import ChainSim, chain_broken
from macrostate_mj.chain.world import World
from macrostate_mj.core.errors import UserError
from macrostate_mj.env.task import TASKS, TailTask


class Localizer(Protocol):
    """A live chain estimator (robots Tail first, metres): `OnlineChain`'s shape."""

    def start(self, poses: np.ndarray) -> None:
        """Every robot's true pose (n, 3) at τ."""

    def observe(self, sensed: np.ndarray) -> None:
        """The Tail's and its neighbour's positions (2, 2) at the next log step."""

    def share(self, poses: np.ndarray) -> None:
        """Every robot's true pose (n, 3) at the latest log step."""

    @property
    def history(self) -> int:
        """Log steps of every pose it needs before its first estimate."""

    @property
    def head_known(self) -> bool:
        """Whether `head` is a shared truth, not an estimate."""

    @property
    def head(self) -> tuple[int, np.ndarray]:
        """(log step, position) of the latest Head estimate."""

    @property
    def head_cov(self) -> np.ndarray | None:
        """Covariance (2, 2) of `head`'s position, NaN where it is the truth; None for an
        estimator without uncertainty."""


@TASKS.register("localize")
class LocalizeTask(TailTask):
    """See the module docstring."""

    def __init__(self, sim: ChainSim, localizer: Callable[[int], Localizer], history: int = 10,
                 observe: str = "truth", random: np.random.RandomState | int | None = None):
        super().__init__(sim, history, observe, random)
        ratio = sim.cfg.command_hz / sim.cfg.log_hz
        if abs(ratio - round(ratio)) > 1e-9:
            raise UserError(f"the localize task steps the estimator every log tick: the "
                            f"command rate {sim.cfg.command_hz:g} Hz must be a whole multiple "
                            f"of the log rate {sim.cfg.log_hz:g} Hz", "scenario")
        self.every = int(round(ratio))
        self.make_localizer = localizer
        self.localizer: Localizer = localizer(sim.n)
        self.truth: list[np.ndarray] = []         # the Head's true position per log step
        self._ticks = 0

    @classmethod
    def create(cls, world: World, data: mujoco.MjData, history: int = 10,
               observe: str = "truth", random: np.random.RandomState | int | None = None,
               localizer: Callable[[int], Localizer] | None = None) -> LocalizeTask:
        """The task with `localizer(n)` making a fresh estimator for n robots per episode."""
        if localizer is None:
            raise UserError("the localize task needs its estimator: pass localizer=..., or make "
                            "macrostate_mj/LocalizeTail-v0 (it carries a trained default)",
                            "localizer")
        return cls(ChainSim(world, data=data), localizer, history, observe, random)

    def initialize_episode(self, physics: dm_mujoco.Physics) -> None:
        super().initialize_episode(physics)
        self.localizer = self.make_localizer(self.sim.n)
        poses = self.sim.poses
        self.localizer.start(poses[::-1])
        self.truth = [poses[0, :2].copy()]
        self._ticks = 0

    def after_step(self, physics: dm_mujoco.Physics) -> None:
        super().after_step(physics)
        self._ticks += 1
        if self._ticks % self.every == 0:          # a log tick: the estimator's next step
            self.localizer.observe(np.array([self._tail[-1][:2], self._neighbour[-1][:2]]))
            self.truth.append(self.sim.poses[0, :2].copy())
            if len(self.truth) <= self.localizer.history:     # the window the model reads
                self.localizer.share(self.sim.poses[::-1])

    def head_error(self) -> float | None:
        """Distance (m) of the latest Head estimate from the truth at its step; None before
        the first estimate."""
        step, xy = self.localizer.head
        if self.localizer.head_known or not np.all(np.isfinite(xy)):
            return None
        return float(np.linalg.norm(xy - self.truth[step]))

    def extra_observations(self) -> dict[str, np.ndarray]:
        step, xy = self.localizer.head
        seen = not self.localizer.head_known and np.all(np.isfinite(xy))
        out = {"estimate": np.append(xy - self._tail[-1][:2], 1.0) if seen else np.zeros(3)}
        cov = self.localizer.head_cov
        if cov is not None:
            flat = np.array([cov[0, 0], cov[0, 1], cov[1, 1]])
            out["estimate_cov"] = flat if seen and np.all(np.isfinite(flat)) else np.zeros(3)
        return out

    def get_reward(self, physics: dm_mujoco.Physics) -> float:
        error = self.head_error()
        return 0.0 if error is None else -error

    def step_info(self) -> dict:
        return {**super().step_info(), "head_error_m": self.head_error()}

    def get_termination(self, physics: dm_mujoco.Physics) -> float | None:
        return 0.0 if chain_broken(self.sim) else super().get_termination(physics)
