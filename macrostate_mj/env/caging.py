"""The caging task (seed §2.5.4): the Tail as the agent of a 6-robot robotarium team whose Head
finds an object and circles it (`chain.caging_mission`). The Tail must help close a ring around it.

Action: the Tail's destination offset, bounded to ±2d here (to leave the chain and encircle,
the Tail moves its destination further than in `explore`). Reward 1 on every tick the team is
caged (the judge `chain.caging_mission.cage_report`), 0 otherwise; the episode ends `SETTLE_S` after
the team was first caged (the net settles), or (discount 0) when the physics faults, and is
truncated at the time limit. Every robot's pose at the start (`team_at_start`, Head first) is
what the Tail knows at τ (§2.4); every `CagingConfig.share_every_s` the team shares its poses
again (`shared`, the intermittent communication of §2.5.3.2). Besides its own and its
neighbour's poses, the Tail observes `object`: the object's centre relative to its own position
(world axes, m) and 1, when the object's surface is within its sensor radius, else zeros: the
local sensing the text grants Head and Tail ("follow along with the surface of an object that
they locally encounter").

`TeamCagingTask` is the same mission for a Head leading two chains (`chain.team`, §5.2), both
Tails agents (`env.multi` serves it to PettingZoo).
"""

from __future__ import annotations

import mujoco
import numpy as np
from dm_control import mujoco as dm_mujoco

from macrostate_mj.chain.caging_mission import CagingConfig, CagingMission, cage_report, start_poses
from macrostate_mj.chain.sim import ChainSim
from macrostate_mj.chain.team import (
    BranchedSim,
    TeamCaging,
    ring_order,
    split_branches,
    team_start_poses,
)
from macrostate_mj.chain.world import World
from macrostate_mj.core.errors import UserError
from macrostate_mj.env.task import TASKS, TailTask

SETTLE_S = 5.0


@TASKS.register("caging")
class CagingTask(TailTask):
    """See the module docstring."""

    def __init__(self, sim: ChainSim, caging: CagingConfig, history: int = 10,
                 observe: str = "truth", random: np.random.RandomState | int | None = None):
        super().__init__(sim, history, observe, random)
        self.caging = caging
        self.max_offset = 2 * sim.cfg.spacing
        self.team_at_start = np.zeros((sim.n, 3))
        self.caged_at: float | None = None
        self.caged = False
        self.shared: np.ndarray | None = None
        self.ring: slice | np.ndarray = slice(None)     # the robots in ring order, for the judge
        self._ticks = 0

    @classmethod
    def create(cls, world: World, data: mujoco.MjData, history: int = 10,
               observe: str = "truth", random: np.random.RandomState | int | None = None,
               caging: CagingConfig | None = None) -> CagingTask:
        """The task on a simulation of `world` with the caging mission of `caging` (default
        `CagingConfig()`), checked against the arena."""
        caging = caging or CagingConfig()
        caging.validate(world.scenario.arena)
        sim = ChainSim(world, data=data, mission=CagingMission(caging))
        return cls(sim, caging, history, observe, random)

    def reset_info(self) -> dict:
        return {"team_at_start": self.team_at_start.copy()}

    def step_info(self) -> dict:
        info = {**super().step_info(), "caged_at": self.caged_at}
        if self.shared is not None:          # the team shares its poses (Head first)
            info["team"] = self.shared.copy()
        return info

    def initialize_episode(self, physics: dm_mujoco.Physics) -> None:
        rng = np.random.default_rng(self.random.randint(2**31))
        start = self.start_poses(rng)
        self.team_at_start = start.copy()
        self.caged_at, self.caged = None, False
        self.shared, self._ticks = None, 0
        self._start_episode(rng, start)

    def start_poses(self, rng: np.random.Generator) -> np.ndarray:
        """The team's start (Head first), drawn from `rng`."""
        return start_poses(self.caging, self.sim.n, self.sim.cfg.spacing, rng,
                           self.sim.cfg.arena)

    def after_step(self, physics: dm_mujoco.Physics) -> None:
        super().after_step(physics)
        self._ticks += 1
        every = self.caging.share_every_s
        period = None if every is None else int(round(every * self.sim.cfg.command_hz))
        self.shared = self.sim.poses.copy() if period and self._ticks % period == 0 else None
        self.caged = cage_report(self.sim.poses[self.ring], self.caging)["caged"]
        if self.caged_at is None and self.caged:
            self.caged_at = self.sim.time

    def extra_observations(self) -> dict[str, np.ndarray]:
        return {"object": self.sense_object(self.sim.poses[self.me, :2])}

    def sense_object(self, position: np.ndarray) -> np.ndarray:
        """(dx, dy, 1): the object's centre relative to `position` (2,) when its surface lies
        within the sensor radius; zeros otherwise. Row by row for positions (k, 2)."""
        rel = np.asarray(self.caging.centre, float) - position
        near = np.linalg.norm(rel, axis=-1, keepdims=True) - self.caging.object_radius <= \
            self.caging.sensor_radius
        return np.where(near, np.concatenate([rel, np.ones_like(rel[..., :1])], axis=-1), 0.0)

    def get_reward(self, physics: dm_mujoco.Physics) -> float:
        return 1.0 if self.caged else 0.0

    def get_termination(self, physics: dm_mujoco.Physics) -> float | None:
        settled = self.caged_at is not None and self.sim.time >= self.caged_at + SETTLE_S - 1e-9
        return 0.0 if settled else super().get_termination(physics)


class TeamCagingTask(CagingTask):
    """The caging task of a Head leading two chains (`chain.team`, seed §5.2): both Tails are
    agents. Observations and actions gain a leading axis, one row per Tail (chain A's first);
    the judge reads the robots in ring order; reward, ending and info are the team's, as in
    `CagingTask`. The team starts as `chain.team.team_start_poses` places it."""

    def __init__(self, sim: BranchedSim, caging: CagingConfig, history: int = 10,
                 observe: str = "truth", random: np.random.RandomState | int | None = None):
        super().__init__(sim, caging, history, observe, random)
        self.me, self.seen, self.ring = sim.tails, sim.neighbours, sim.mission.ring

    @classmethod
    def create(cls, world: World, data: mujoco.MjData, history: int = 10,
               observe: str = "truth", random: np.random.RandomState | int | None = None,
               caging: CagingConfig | None = None, tails: int = 2) -> TeamCagingTask:
        """The task of `tails` chains (only 2 ring an object) with the mission of `caging`."""
        if tails != 2:
            raise UserError(f"the caging team rings the object with two chains: tails must be "
                            f"2, got {tails!r}", "tails")
        caging = caging or CagingConfig()
        caging.validate(world.scenario.arena)
        branches = split_branches(len(world.names), tails)
        sim = BranchedSim(world, branches, data=data,
                          mission=TeamCaging(caging, ring_order(branches)))
        return cls(sim, caging, history, observe, random)

    def start_poses(self, rng: np.random.Generator) -> np.ndarray:
        return team_start_poses(self.caging, self.sim.branches, self.sim.cfg.spacing, rng,
                                self.sim.cfg.arena)
