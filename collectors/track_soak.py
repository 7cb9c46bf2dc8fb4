"""`macrostate-mj soak --track`: many seeds of a scenario filmed and tracked, each run's
tracking health judged against the scenario's `[tracking]` limits, so that a lab is known to
track well (or known not to) before anyone collects in it.

Seed s runs exactly `simulate --track --seed s` (the same `collectors.simulate.simulate_chain`).
Each seed is a cached task: an interrupted soak resumes.
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import asdict, dataclass
from typing import ClassVar

from macrostate_mj.chain.physics_soak import SoakRunTask, SoakTask


@dataclass(frozen=True)
class TrackedRun:
    """One seed's tracking health (figures per robot as `vision.health` reports them)."""

    seed: int
    fault: str | None                # a physics fault ends the run early; the health covers
    #                                  what ran
    health: dict
    findings: list[str]
    summary: str
    frames: int
    wall_s: float


def track_one(task: SoakTask) -> TrackedRun:
    from collectors.simulate import simulate_chain

    cfg = task.scenario
    t0 = time.perf_counter()
    ran = simulate_chain(cfg, task.robots, task.seconds, task.seed, track=True)
    report = ran.tracker.health.report(ran.log)
    return TrackedRun(task.seed, None if ran.failure is None else str(ran.failure),
                      report.as_dict(), [f.describe() for f in report.judged(cfg)],
                      report.described(cfg), ran.tracker.frames,
                      time.perf_counter() - t0)


class TrackSoakTask(SoakRunTask):
    """One seed's tracked soak as a cached task, keyed as the physics soak's (its task and the
    scenario) under a stage of its own."""

    stage: ClassVar[str] = "track-soak-run"
    version: ClassVar[int] = 2          # 2: rows, hidden and heading figures
    result: ClassVar[type] = TrackedRun

    def compute(self) -> dict[str, bytes]:
        return {"run.json": json.dumps(asdict(track_one(self.task))).encode()}


def track_summary(runs: list[TrackedRun]) -> dict:
    """The tracked soak's one row: unhealthy runs, and the worst figures over every robot of
    every run."""
    from macrostate_mj.vision.health import TrackingHealth, worst_of

    worst = worst_of([TrackingHealth.from_dict(r.health) for r in runs]).robots
    finite = [r for r in worst if r.detected_frames > 0]
    def clean(v: float) -> float | None:          # JSON has no NaN
        return None if math.isnan(v) else v

    return {
        "runs": len(runs), "unhealthy": sum(bool(r.findings) for r in runs),
        "faults": sum(r.fault is not None for r in runs),
        "min_detected": clean(min((r.detected_share[0] for r in worst if r.frames),
                                  default=math.nan)),
        "max_hidden": clean(max((r.hidden_share[0] for r in worst if r.frames + r.hidden),
                                default=math.nan)),
        "max_median_mm": clean(max((r.median_mm for r in finite), default=math.nan)),
        "max_p99_mm": clean(max((r.p99_mm for r in finite), default=math.nan)),
        "max_heading_deg": clean(max((r.heading_deg for r in finite), default=math.nan)),
        "max_heading_p99_deg": clean(max((r.heading_p99_deg for r in finite),
                                         default=math.nan)),
        "max_heading_flips": clean(max((r.heading_flips for r in finite), default=math.nan)),
        "max_identity": clean(max((r.identity for r in worst if r.frames), default=math.nan)),
        "frames": sum(r.frames for r in runs),
        "wall_s_per_run": sum(r.wall_s for r in runs) / len(runs),
    }
