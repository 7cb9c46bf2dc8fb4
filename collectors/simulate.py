"""One chain simulated from a seed, its poses logged (and, with `track`, filmed and tracked):
what `macrostate-mj simulate` runs. Recorders that draw (video, rerun) are made by the caller,
which sits above `viz`, through `recorders(sim, tracker)`."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import pyarrow as pa

from macrostate_mj.chain.health import PhysicsError
from macrostate_mj.chain.scenario import ScenarioConfig
from macrostate_mj.chain.sim import ChainSim, Every, Hook, PoseLog, Tracker
from macrostate_mj.chain.world import World, build_world
from macrostate_mj.formats.poses import poses_table

Recorders = Callable[[ChainSim, Tracker | None], list[Hook]]


def imaging_rng(seed: int) -> np.random.Generator:
    """The camera chain's own stream: tracking never changes the simulated trajectory."""
    return np.random.default_rng([seed, 1])


@dataclass
class ChainRun:
    """A finished (or physics-failed) run: the hooks kept what was simulated up to a fault."""

    world: World
    sim: ChainSim
    log: PoseLog
    tracker: object | None
    failure: PhysicsError | None
    timings: dict[str, float] = field(default_factory=dict)   # build, run (s)

    def poses(self) -> pa.Table:
        """The pose log as `formats.poses` writes it (tracked columns with `track`)."""
        times, poses, waypoints = self.log.arrays()
        return poses_table(self.world.names, times, poses, waypoints, self.log.tracked_arrays())


def simulate_chain(cfg: ScenarioConfig, robots: int, seconds: float, seed: int,
                   track: bool = False, recorders: Recorders | None = None,
                   progress: Callable[[float], None] | None = None) -> ChainRun:
    """Simulate `robots` on `cfg` for `seconds` from `seed`; hooks in order: the camera chain
    (with `track`), the pose log, then the caller's recorders. A physics fault ends the run
    early and is returned, not raised."""
    t0 = time.perf_counter()
    world = build_world(cfg, robots)
    sim = ChainSim(world)
    sim.reset(np.random.default_rng(seed))
    timings = {"build": time.perf_counter() - t0}

    hooks: list[Hook] = []
    tracker = None
    if track:
        from macrostate_mj.vision.camera_chain import CameraChain

        tracker = CameraChain(sim, rng=imaging_rng(seed))
        hooks.append(tracker)
    log = PoseLog(world.names, tracker=tracker)
    hooks.append(Every(1 / cfg.log_hz, log.append, sim.log_phase))
    hooks += recorders(sim, tracker) if recorders is not None else []
    t0 = time.perf_counter()
    failure: PhysicsError | None = None
    try:
        sim.episode(seconds, hooks, progress)
    except PhysicsError as err:
        failure = err
    timings["run"] = time.perf_counter() - t0
    return ChainRun(world, sim, log, tracker, failure, timings)
