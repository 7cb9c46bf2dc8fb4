"""One collection episode: an independent task with its own derived seeds.

Seeds are derived from (collection seed, episode index) only, so an episode's output does not
depend on which worker, process or machine runs it, or in which order.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import pyarrow as pa

from collectors.randomize import (
    Randomization,
    randomize_model,
    randomized_noise,
    randomized_scenario,
)
from macrostate_mj.chain.scenario import ScenarioConfig
from macrostate_mj.formats.poses import poses_table
from macrostate_mj.tails.collection import PolicyConfig, PolicySpec
from macrostate_mj.vision.imaging import NoiseConfig


@dataclass(frozen=True)
class EpisodeSpec:
    scenario: ScenarioConfig     # resolved where the command or API call began
    robots: int
    seconds: float              # driving time logged after the warm-up
    warmup: float               # settling time at the start (s), logged but never cut
    seed: int
    index: int
    policy: PolicySpec = field(default_factory=PolicyConfig)
    noise: NoiseConfig | None = None      # None: the scenario's imaging noise
    randomize: Randomization | None = None

    def rng(self, stream: int) -> np.random.Generator:
        """Stream 0: physics and planner; 1: imaging; 2: policy; 3: domain randomization."""
        return np.random.default_rng([self.seed, self.index, stream])


def run_episode(spec: EpisodeSpec) -> tuple[int, pa.Table | None, dict]:
    """Simulate, film and track one episode; return its long-format log with an `episode`
    column and timing figures, or no table and `{"failure": ...}` when its physics failed.
    Runs anywhere: a local process or a Ray worker."""
    from macrostate_mj.chain.health import PhysicsError
    from macrostate_mj.chain.sim import ChainSim, Every, PoseLog
    from macrostate_mj.chain.world import build_world
    from macrostate_mj.vision.camera_chain import CameraChain

    t0 = time.perf_counter()
    cfg, factors = spec.scenario, {}
    noise = spec.noise or cfg.imaging
    if spec.randomize is not None:
        factors = spec.randomize.draw(spec.rng(3))
        cfg, noise = randomized_scenario(cfg, factors), randomized_noise(noise, factors)
    world = build_world(cfg, spec.robots)
    randomize_model(world, factors)
    sim = ChainSim(world)
    sim.reset(spec.rng(0))
    chain = CameraChain(sim, noise, rng=spec.rng(1))
    log = PoseLog(world.names, tracker=chain)
    policy = spec.policy.build(spec.rng(2), chain)
    step = 1 / cfg.log_hz
    hooks = [chain, Every(step, policy, sim.log_phase), Every(step, log.append, sim.log_phase)]
    try:
        sim.episode(spec.warmup + spec.seconds, hooks)
    except PhysicsError as err:
        return spec.index, None, {"failure": str(err)}
    times, poses, waypoints = log.arrays()
    table = poses_table(world.names, times, poses, waypoints, log.tracked_arrays())
    table = table.append_column("episode", pa.array(np.full(table.num_rows, spec.index)))
    stats = {"seconds": time.perf_counter() - t0, "frames": chain.frames,
             "dropped": chain.dropped, "windowed": chain.windowed,
             "rendered": chain.rendered, "health": chain.health.report(log).as_dict(),
             "steps": int(round(sim.time / sim.model.opt.timestep)),
             "decisions": policy.records(), "randomized": factors}
    return spec.index, table, stats
