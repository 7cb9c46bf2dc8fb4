"""`soak`: many seeds of one scenario in parallel; a table of faults and worst figures."""

from __future__ import annotations

import json
from pathlib import Path

import typer

from macrostate_mj.app.cli.app import app
from macrostate_mj.app.params import (
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
                 ("min_detected", "min detected (rows)", ".4f"),
                 ("max_hidden", "max hidden", ".4f"), ("max_median_mm", "max median mm", ".2f"),
                 ("max_p99_mm", "max p99 mm", ".2f"),
                 ("max_heading_p99_deg", "max heading p99 deg", ".1f"),
                 ("max_heading_flips", "max flipped", ".4f"),
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
    from macrostate_mj.app.usecases.soak import check
    from macrostate_mj.app.usecases.soak import soak as run_soak
    from macrostate_mj.core.progress import sim_progress

    with sim_progress(seeds, f"soak {scenario.name} {robots} robots", unit="runs") as bar:
        row, runs = run_soak(scenario, robots, seeds, seconds, first_seed, workers, ray,
                             check_hz, out, track, overwrite, bar)
    columns = TRACK_COLUMNS if track else COLUMNS
    if as_json:
        print(json.dumps(row), flush=True)
    else:
        typer.echo(f"{scenario.name} x {robots} robots, {seconds:g} s each, seeds "
                   f"{first_seed}..{first_seed + seeds - 1}")
        typer.echo("  ".join(f"{head:>{max(len(head), 6)}}" for _, head, _ in columns))
        typer.echo("  ".join(f"{row[key]:>{max(len(head), 6)}{fmt}}" if row[key] is not None
                             else f"{'n/a':>{max(len(head), 6)}}" for key, head, fmt in columns))
        if row.get("warnings"):
            typer.echo(f"MuJoCo warnings: {row['warning_kinds']}")
    check(runs, scenario, robots, seconds, track)
