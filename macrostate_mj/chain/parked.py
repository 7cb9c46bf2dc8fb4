"""Does a parked chain stand still? A property of a lab's rules and robots, not of one run.

The chain starts in a line behind its Head, the Head drives to a fixed point on that line and
stays; after `settle` seconds each robot must keep within `MOVED_M` of where it stood and turn
less than `TURNED_DEG` over the next `watch` seconds. Stiff gains with rear robots that back
off from the robot ahead fail it (a robot that may not reverse turns on the spot to back off),
so `sysid` keeps only candidates that pass it (docs: decisions/sysid).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from macrostate_mj.core.angles import wrap_angle

if TYPE_CHECKING:
    from macrostate_mj.chain.scenario import ScenarioConfig

MOVED_M = 0.002         # a parked robot moves less than this (m) ...
TURNED_DEG = 1.0        # ... and turns less than this (degrees) while watched
SEEDS = (0, 1, 2)       # start seeds (the wheels drawn per episode differ by seed)
TEAMS = (3, 5)          # the real deployments' sizes: a rule that parks 3 robots still may
#                         not park 5 (the stiff factors of the parked-chain physics test: 3
#                         still, 5 moved 2.7 cm and turned 17 degrees)


@dataclass(frozen=True)
class Parked:
    """The most any robot moved (m) and turned (degrees) while watched, over the seeds."""

    moved_m: float
    turned_deg: float

    @property
    def still(self) -> bool:
        return self.moved_m < MOVED_M and self.turned_deg < TURNED_DEG


def parks_still(cfg: ScenarioConfig, teams: tuple[int, ...] = TEAMS) -> dict:
    """`parked` for each team size: {"moved_m", "turned_deg"} (the most of any), "still"."""
    results = [parked(cfg, n) for n in teams]
    worst = Parked(max(r.moved_m for r in results), max(r.turned_deg for r in results))
    return {"moved_m": worst.moved_m, "turned_deg": worst.turned_deg, "still": worst.still,
            "teams": list(teams)}


def parked(cfg: ScenarioConfig, robots: int = 3, seeds: tuple[int, ...] = SEEDS,
           settle: float = 90.0, watch: float = 60.0) -> Parked:
    """Park a chain of `robots` behind a straight Head once per start seed and watch it."""
    from macrostate_mj.chain.planners import FixedWaypoint
    from macrostate_mj.chain.sim import ChainSim
    from macrostate_mj.chain.world import build_world

    half = np.array(cfg.arena) / 2 - cfg.wall_margin
    start = np.array([[-half[0] + (robots - 1 - i) * cfg.spacing, 0.0, 0.0]
                      for i in range(robots)])
    sim = ChainSim(build_world(cfg, robots), planner=FixedWaypoint((float(half[0]), 0.0)))
    moved = turned = 0.0
    for seed in seeds:
        sim.reset(np.random.default_rng(seed), start=start)
        sim.run(settle, [])
        before = sim.poses.copy()
        sim.run(watch, [])
        after = sim.poses
        moved = max(moved, float(np.linalg.norm(after[:, :2] - before[:, :2], axis=1).max()))
        turned = max(turned, float(np.degrees(np.abs(wrap_angle(after[:, 2] - before[:, 2])))
                                   .max()))
    return Parked(moved, turned)
