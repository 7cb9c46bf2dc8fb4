"""`soak`: many seeds of one scenario in parallel; a table of faults and worst figures."""

from __future__ import annotations

import contextlib
import json
from pathlib import Path

import typer

from macrostate_mj.app.cli.app import app
from macrostate_mj.app.cli.params import (
    MAX_SECONDS,
    MAX_WORKERS,
    Count,
    OutputDir,
    Positive,
    Scenario,
    Seed,
    Switch,
)

COLUMNS = [("runs", "runs", "d"), ("tips", "tips", "d"), ("nans", "NaNs", "d"),
           ("escapes", "escapes", "d"), ("climbs", "climbs", "d"),
           ("intrusions", "intrusions", "d"),
           ("max_penetration_mm", "max pen. mm", ".2f"), ("min_upright", "min upright", ".4f"),
           ("max_lift_mm", "max lift mm", ".2f"), ("warnings", "warnings", "d"),
           ("steps_per_s_per_worker", "steps/s/worker", ".0f")]
TRACK_COLUMNS = [("runs", "runs", "d"), ("unhealthy", "unhealthy", "d"), ("faults", "faults", "d"),
                 ("min_detected", "min detected", ".4f"), ("max_median_mm", "max median mm", ".2f"),
                 ("max_p99_mm", "max p99 mm", ".2f"), ("max_heading_deg", "max heading deg", ".2f"),
                 ("max_identity", "max identity", ".4f"), ("wall_s_per_run", "s/run", ".1f")]


@app.command()
def soak(
    scenario: str = Scenario,
    robots: int = Count(5, "Chain length N.", min=2),
    seeds: int = Count(24, "Number of seeds (runs).", max=10**6),
    seconds: float = Positive(600.0, "Simulated seconds per run.", max=MAX_SECONDS),
    first_seed: int = Seed(0, "Seeds are first-seed, first-seed + 1, ..."),
    workers: int = Count(1, "Local worker processes.", max=MAX_WORKERS),
    ray: str = typer.Option(None, "--ray", help="Run seeds on Ray: local, auto or ADDRESS."),
    check_hz: float = Positive(50.0, "Health checks per simulated second (a fault "
                                   "is then pinned to its physics step)."),
    out: Path = OutputDir(None, "Also write soak.json, manifest.json and runs/ (one file "
                             "per finished seed: a rerun resumes)."),
    as_json: bool = Switch(False, "Print the summary as one JSON line.", "--json/--table"),
    track: bool = Switch(False, "Film and track every run instead (as simulate --track): "
                         "report each run's tracking health against the scenario's [tracking] "
                         "limits; exit 1 if any run is unhealthy."),
    overwrite: bool = Switch(False, "Replace an existing soak.json."),
) -> None:
    """Run many seeds and count tips, NaNs, escapes, climbing and obstacle intrusions; exit 1
    if any run faulted. With --track, judge every run's tracking health instead."""
    from macrostate_mj.app.simulate import SimulateRequest, reproduce_command
    from macrostate_mj.chain.soak import run_records, soak_tasks, summary
    from macrostate_mj.chain.soak import soak as run_soak
    from macrostate_mj.core.cache import TaskCache
    from macrostate_mj.core.errors import RunFailure
    from macrostate_mj.core.io import write_json_atomic
    from macrostate_mj.core.progress import sim_progress
    from macrostate_mj.core.run import Run

    tasks = soak_tasks(scenario, robots, seeds, seconds, first_seed, check_hz)
    name = scenario.name
    if track:
        from collectors.track_soak import TrackSoakTask, track_summary
        from macrostate_mj.chain.rendered import check_rendered_colours

        check_rendered_colours(scenario, robots)    # refused before any run, as simulate does

        kind, columns, tabulate = TrackSoakTask, TRACK_COLUMNS, track_summary
    else:
        kind, columns, tabulate = None, COLUMNS, lambda runs: summary(runs, workers)
    with contextlib.ExitStack() as stack:
        config = {"tasks": tasks[0], "seeds": seeds, **({"track": True} if track else {})}
        run = None if out is None else stack.enter_context(
            Run(out, "soak", config, first_seed, ["soak.json"], overwrite))
        bar = stack.enter_context(sim_progress(seeds, f"soak {name} {robots} robots",
                                               unit="runs"))
        runs = run_soak(tasks, workers, ray, bar, None if out is None
                        else TaskCache(out / "cache"), **({"kind": kind} if kind else {}))
        row = {"scenario": name, "robots": robots, "seconds": seconds, **tabulate(runs)}
        if run is not None:
            write_json_atomic(out / "soak.json", {"summary": row, "runs": run_records(runs)})
            run.record(workers=workers, outputs={"soak": str(out / "soak.json")})
    if as_json:
        print(json.dumps(row), flush=True)
    else:
        typer.echo(f"{name} x {robots} robots, {seconds:g} s each, seeds "
                   f"{first_seed}..{first_seed + seeds - 1}")
        typer.echo("  ".join(f"{head:>{max(len(head), 6)}}" for _, head, _ in columns))
        typer.echo("  ".join(f"{row[key]:>{max(len(head), 6)}{fmt}}" if row[key] is not None
                             else f"{'n/a':>{max(len(head), 6)}}" for key, head, fmt in columns))
        if row.get("warnings"):
            typer.echo(f"MuJoCo warnings: {row['warning_kinds']}")
    if track:
        sick = [r for r in runs if r.findings]
        if sick:
            first = sick[0].seed
            again = SimulateRequest(scenario, robots, seconds, first, Path(f"soak_seed{first}"),
                                    track=True)
            raise RunFailure(f"{len(sick)} of {len(runs)} runs tracked unhealthily; first: seed "
                             f"{first}: {sick[0].findings[0]}; reproduce: "
                             f"{reproduce_command(again)}")
    bad = [r for r in runs if r.fault is not None]
    if bad:
        first = bad[0].seed
        again = SimulateRequest(scenario, robots, seconds, first, Path(f"soak_seed{first}"))
        raise RunFailure(f"{len(bad)} of {len(runs)} runs faulted; first: seed {first}: "
                         f"{bad[0].reason}; reproduce: {reproduce_command(again)}")
