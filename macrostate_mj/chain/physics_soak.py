"""The physics soak behind `macrostate-mj soak`: many seeds of one scenario in parallel, in the
spirit of Menagerie's `model_test`: a physics claim is a property over seeds nobody tuned to,
not one trajectory.

Seed s runs exactly the trajectory of `simulate --seed s` (same reset, same controller ticks;
the extra health checks only cut the C stepping into shorter stretches, which changes nothing).
"""

from __future__ import annotations

import json
import tempfile
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, replace
from typing import TYPE_CHECKING, ClassVar

import numpy as np

from macrostate_mj.chain.health import Fault, PhysicsError
from macrostate_mj.core.cache import TaskCache, run_tasks, task_key
from macrostate_mj.core.checks import check_count, check_seed
from macrostate_mj.core.errors import UserError

if TYPE_CHECKING:
    from macrostate_mj.chain.scenario import ScenarioConfig
    from macrostate_mj.chain.scenarios import ScenarioRef


@dataclass(frozen=True)
class SoakTask:
    """One seed's soak of a resolved scenario (a built-in, a file, or a variant that no file
    holds: another robot, say)."""

    scenario: ScenarioConfig
    robots: int
    seconds: float
    seed: int
    check_hz: float


@dataclass(frozen=True)
class SoakRun:
    seed: int
    fault: str | None            # a `Fault` name, None when the run finished healthy
    reason: str | None
    simulated_s: float
    max_lift_mm: float
    min_upright: float
    max_penetration_mm: float
    warnings: dict[str, int]
    steps: int
    wall_s: float


def soak_one(task: SoakTask) -> SoakRun:
    """One seed to its end or its first fault, health checked `check_hz` times a second."""
    from macrostate_mj.chain.sim import ChainSim
    from macrostate_mj.chain.world import build_world

    world = build_world(task.scenario, task.robots)
    sim = ChainSim(world)
    sim.reset(np.random.default_rng(task.seed))
    dt = world.model.opt.timestep
    sim.check_steps = max(1, int(round(1 / (task.check_hz * dt))))
    fault = reason = None
    t0 = time.perf_counter()
    try:
        sim.run(task.seconds, [])
    except PhysicsError as err:
        fault, reason = err.fault.fault.name, str(err)
    wall = time.perf_counter() - t0
    s = sim.monitor.stats
    return SoakRun(task.seed, fault, reason, sim.time, s.max_lift_mm, s.min_upright,
                   s.max_penetration_mm, s.warnings, int(round(sim.time / dt)), wall)


def soak_tasks(scenario: ScenarioRef, robots: int, seeds: int, seconds: float,
               first_seed: int = 0, check_hz: float = 50.0) -> list[SoakTask]:
    """The seeds' tasks; a built-in's name or a scenario file is resolved here, once."""
    from macrostate_mj.chain.scenarios import get_scenario
    from macrostate_mj.chain.world import validate_chain

    scenario = get_scenario(scenario)
    validate_chain(scenario, robots, seconds)
    check_count(seeds, "seeds")
    check_seed(first_seed, "first_seed")
    if not (0 < check_hz < float("inf")):
        raise UserError(f"check_hz must be a positive number, got {check_hz}", "check_hz")
    return [SoakTask(scenario, robots, seconds, first_seed + k, check_hz) for k in range(seeds)]


class SoakRunTask:
    """One seed's soak as a cached task, keyed by its task and the scenario's constants (a
    refit scenario is soaked again)."""

    stage: ClassVar[str] = "soak-run"
    version: ClassVar[int] = 1
    result: ClassVar[type] = SoakRun        # what its run.json holds

    def __init__(self, task: SoakTask):
        self.task = task

    def key(self) -> str:
        return task_key(self.stage, self.version,
                        replace(self.task, scenario=self.task.scenario.as_made()))

    def compute(self) -> dict[str, bytes]:
        return {"run.json": json.dumps(asdict(soak_one(self.task))).encode()}


def soak(tasks: list[SoakTask], workers: int = 1, ray: str | None = None,
         progress: Callable[[int, int], None] | None = None, cache: TaskCache | None = None,
         kind: type = SoakRunTask) -> list:
    """Run every task as a `kind` (the physics soak's `SoakRunTask`, or another seed's task
    with a `result` type: the tracked soak's); results in seed order whatever the number of
    workers. With `cache`, each finished run is kept there and a rerun skips the seeds it holds
    (an interrupted soak resumes); without, the runs are kept in a temporary folder.
    `progress(runs done, of them resumed)` follows the runs."""
    if workers < 1:
        raise UserError(f"workers must be at least 1, got {workers}", "workers")
    with tempfile.TemporaryDirectory() as tmp:
        runs, resumed = [], 0
        for outcome in run_tasks(cache or TaskCache(tmp), [kind(t) for t in tasks],
                                 workers, ray):
            runs.append(kind.result(**json.loads((outcome.folder / "run.json").read_text())))
            resumed += outcome.cached
            if progress:
                progress(len(runs), resumed)
    return sorted(runs, key=lambda r: r.seed)


def summary(runs: list[SoakRun], workers: int) -> dict[str, float | int | str]:
    """The soak table's one row: counts of each fault and the worst figures over all runs."""
    counts = {f: sum(r.fault == f.name for r in runs) for f in Fault}
    warnings: dict[str, int] = {}
    for r in runs:
        for k, v in r.warnings.items():
            warnings[k] = warnings.get(k, 0) + v
    steps, wall = sum(r.steps for r in runs), sum(r.wall_s for r in runs)
    return {
        "runs": len(runs), "tips": counts[Fault.TIP], "nans": counts[Fault.NAN],
        "escapes": counts[Fault.ESCAPE], "climbs": counts[Fault.LIFT],
        "intrusions": counts[Fault.INTRUDE],
        "max_penetration_mm": max(r.max_penetration_mm for r in runs),
        "min_upright": min(r.min_upright for r in runs),
        "max_tilt_deg": float(np.degrees(np.arccos(min(r.min_upright for r in runs)))),
        "max_lift_mm": max(r.max_lift_mm for r in runs),
        "warnings": sum(warnings.values()),
        "warning_kinds": ",".join(f"{k}:{v}" for k, v in sorted(warnings.items())) or "-",
        "simulated_s": sum(r.simulated_s for r in runs),
        "steps_per_s_per_worker": steps / max(wall, 1e-9),
        "workers": workers,
    }


def run_records(runs: list[SoakRun]) -> list[dict]:
    return [asdict(r) for r in runs]
