"""`soak` as a use case: many seeds of one scenario, as physics runs or tracked runs, under a
run in `out` when one is given (a rerun resumes from the finished seeds); the summary row, and
the failure that names the first bad seed and the command that reproduces it."""

from __future__ import annotations

import contextlib
import json
from collections.abc import Callable
from pathlib import Path

from macrostate_mj.app.results.sources import (
    load,
    root,
    source,
)
from macrostate_mj.chain.scenario import ScenarioConfig
from macrostate_mj.core.errors import RunFailure
from macrostate_mj.core.evidence import Table
from macrostate_mj.core.run import MANIFEST


def soak(scenario: ScenarioConfig, robots: int, seeds: int, seconds: float, first_seed: int,
         workers: int, ray: str | None, check_hz: float, out: Path | None, track: bool,
         overwrite: bool, bar: Callable[..., None] | None = None) -> tuple[dict, list]:
    """The summary row and every seed's run (in seed order); `bar(done, cached)` follows them."""
    from macrostate_mj.chain.physics_soak import run_records, soak_tasks, summary
    from macrostate_mj.chain.physics_soak import soak as run_soak
    from macrostate_mj.core.cache import TaskCache
    from macrostate_mj.core.io import write_json_atomic
    from macrostate_mj.core.run import Run

    tasks = soak_tasks(scenario, robots, seeds, seconds, first_seed, check_hz)
    if track:
        from collectors.track_soak import TrackSoakTask, track_summary
        from macrostate_mj.chain.filmed import check_filmed

        check_filmed(scenario, robots)      # refused before any run, as simulate does
        kind, tabulate = TrackSoakTask, track_summary
    else:
        kind, tabulate = None, lambda runs: summary(runs, workers)
    with contextlib.ExitStack() as stack:
        config = {"tasks": tasks[0], "seeds": seeds, **({"track": True} if track else {})}
        run = None if out is None else stack.enter_context(
            Run(out, "soak", config, first_seed, ["soak.json"], overwrite))
        runs = run_soak(tasks, workers, ray, bar, None if out is None
                        else TaskCache(out / "cache"), **({"kind": kind} if kind else {}))
        row = {"scenario": scenario.name, "robots": robots, "seconds": seconds,
               **tabulate(runs)}
        if run is not None:
            write_json_atomic(out / "soak.json", {"summary": row, "runs": run_records(runs)})
            run.record(workers=workers, outputs={"soak": str(out / "soak.json")})
    return row, runs


def check(runs: list, scenario: ScenarioConfig, robots: int, seconds: float,
          track: bool) -> None:
    """A `RunFailure` naming the first unhealthy (tracked) or faulted seed, with the
    `simulate` command that reproduces it; nothing when every run was sound."""
    from macrostate_mj.app.usecases.simulate import SimulateRequest, reproduce_command

    failures = (([r for r in runs if r.findings] if track else []), "tracked unhealthily",
                lambda r: r.findings[0], track), \
               ([r for r in runs if r.fault is not None], "faulted", lambda r: r.reason, False)
    for failed, what, reason, tracked in failures:
        if failed:
            first = failed[0].seed
            again = SimulateRequest(scenario, robots, seconds, first, Path(f"soak_seed{first}"),
                                    track=tracked)
            raise RunFailure(f"{len(failed)} of {len(runs)} runs {what}; first: seed {first}: "
                             f"{reason(failed[0])}; reproduce: {reproduce_command(again)}")


# Its tables and numbers as the docs show them ----------------------------------------

@source
def soak_table(*folders: str) -> Table:
    """Soaks' summaries, one column each: runs, simulated time and every fault count."""
    summaries = [load(f"{folder}/soak.json")["summary"] for folder in folders]  # type: ignore[index]
    keys = ["scenario", "robots", "runs", "seconds", "tips", "nans", "escapes", "climbs",
            "intrusions", "warnings", "max_tilt_deg", "max_lift_mm"]
    rows = [["figure", *(["value"] if len(folders) == 1 else [Path(f).name for f in folders])]]
    for key in (k for k in keys if k in summaries[0]):
        rows.append([key, *(_soak_cell(summary[key]) for summary in summaries)])
    return rows


def _soak_cell(value: object) -> str:
    if isinstance(value, float):
        return f"{value:.2f}" if not value.is_integer() else str(int(value))
    return str(value)


@source
def track_soak(folder: str) -> Table:
    """Tracked soaks, one sub-folder a lab (`soak --track --out`): its summary row each."""
    rows = [["folder", "markers", "robots", "runs x s", "unhealthy", "min detected (rows)",
             "max hidden", "max median mm", "max p99 mm", "max heading p99 deg", "max flipped",
             "max identity", "s/run"]]
    for soak_file in sorted((root() / folder).glob("*/soak.json")):
        summary = json.loads(soak_file.read_text())["summary"]
        manifest = json.loads((soak_file.parent / MANIFEST).read_text())
        scenario = manifest["config"]["tasks"]["scenario"]
        kind = scenario.get("markers", {}).get("dictionary") and "aruco" or "colour"
        rows.append([soak_file.parent.name, kind, str(summary["robots"]),
                     f"{summary['runs']} x {summary['seconds']:g}", str(summary["unhealthy"]),
                     f"{summary['min_detected']:.4f}", f"{summary['max_hidden']:.4f}",
                     f"{summary['max_median_mm']:.2f}", f"{summary['max_p99_mm']:.2f}",
                     f"{summary['max_heading_p99_deg']:.1f}",
                     f"{summary['max_heading_flips']:.4f}", f"{summary['max_identity']:.4f}",
                     f"{summary['wall_s_per_run']:.1f}"])
    return rows

