"""`simulate` and `export-mjcf`."""

from __future__ import annotations

from pathlib import Path

import typer

from macrostate_mj.app.cli.app import app
from macrostate_mj.core.progress import sim_progress


@app.command()
def simulate(
    scenario: str = typer.Option("lab", help="lab, webots or robotarium."),
    robots: int = typer.Option(5, help="Chain length N (Head, N-2 Followers, Tail)."),
    seconds: float = typer.Option(60.0, help="Simulated seconds."),
    seed: int = typer.Option(0, help="Seed of every random draw."),
    out: Path = typer.Option(..., help="Output folder (poses.parquet, manifest.json)."),
    video: Path = typer.Option(None, help="Also render the overhead camera to this MP4."),
    rerun: Path = typer.Option(None, help="Also log the run to this rerun .rrd file."),
    overlays: str = typer.Option("ids,waypoint,trails", help="Video overlays, comma-separated "
                                 "from ids, waypoint, trails; 'none' for the bare camera."),
    head_speed: float = typer.Option(None, help="Override the scenario's Head speed (m/s)."),
    track: bool = typer.Option(False, help="Film with the overhead camera and track the "
                               "markers at the command rate: adds x_trk, y_trk, theta_trk, "
                               "detected."),
    overwrite: bool = typer.Option(False, help="Replace existing outputs."),
) -> None:
    """Simulate a robot chain; write its pose log (and optionally a video and a rerun file)."""
    from macrostate_mj.app.simulate import SimulateRequest, check_request, simulate_run

    req = SimulateRequest(scenario, robots, seconds, seed, out, video, rerun, overwrite,
                          head_speed=head_speed, track=track, overlays=overlays)
    check_request(req)
    with sim_progress(seconds, "simulating") as advance:
        written = simulate_run(req, advance)
    for kind, path in written.items():
        typer.echo(f"{kind:<9} {path}")


@app.command("export-mjcf")
def export_mjcf(
    scenario: str = typer.Option("lab", help="lab, webots or robotarium."),
    robots: int = typer.Option(5, help="Chain length N."),
    out: Path = typer.Option(..., help="Output .xml file."),
    overwrite: bool = typer.Option(False, help="Replace an existing file."),
) -> None:
    """Write one self-contained MJCF of a scenario with N robots (opens in MuJoCo's viewer)."""
    from macrostate_mj.chain.scenarios import scenario_for
    from macrostate_mj.chain.world import build_world, validate_chain
    from macrostate_mj.core.io import check_writable_file, write_text_atomic

    cfg = scenario_for(scenario)
    validate_chain(cfg, robots, 1.0)
    check_writable_file(out, overwrite, "--out")
    write_text_atomic(out, build_world(cfg, robots).to_xml())
    typer.echo(f"mjcf      {out}")
