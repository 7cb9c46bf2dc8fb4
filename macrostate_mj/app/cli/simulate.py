"""`simulate` and `export-mjcf`."""

from __future__ import annotations

from pathlib import Path

import typer

from macrostate_mj.app.cli.app import app
from macrostate_mj.app.params import (
    MAX_SECONDS,
    Choice,
    Count,
    OutputDir,
    OutputFile,
    Positive,
    Scenario,
    Seed,
    Switch,
)
from macrostate_mj.core.progress import sim_progress


@app.command()
def simulate(
    scenario: str = Scenario,
    robots: int = Count(5, "Chain length N (Head, N-2 Followers, Tail).", min=2),
    seconds: float = Positive(60.0, "Simulated seconds.", max=MAX_SECONDS),
    seed: int = Seed(),
    out: Path = OutputDir(..., "Output folder (poses.parquet, manifest.json)."),
    video: Path = OutputFile(None, "Also render the overhead camera to this MP4: its view "
                             "through the scenario's lens, overlays where they lie in it.",
                             (".mp4",)),
    video_view: str = Choice("camera", "What --video shows: the camera's view (through its "
                             "lens distortion, as the tracker saw it) or the undistorted "
                             "pinhole render (a diagnostic).", ("camera", "undistorted")),
    camera_video: Path = OutputFile(None, "With --track, also write the raw frames the tracker "
                                    "was handed (lens and imaging noise, no overlays) to this "
                                    "MP4, their times beside it in FILE.times.csv; `macrostate-mj "
                                    "track` tracks it offline.", (".mp4",)),
    rerun: Path = OutputFile(None, "Also log the run to this rerun .rrd file.", (".rrd",)),
    overlays: str = typer.Option("all", help="Video overlays, comma-separated from ids, "
                                 "waypoint, trails, clock, walls, scale, detections (the "
                                 "tracker's, with --track); 'all', or 'none' for the bare "
                                 "camera."),
    head_speed: float = Positive(None, "Override the scenario's Head speed (m/s), up to the "
                                 "robot's top speed."),
    track: bool = Switch(False, "Film with the overhead camera and track the markers at the "
                         "command rate: adds x_trk, y_trk, theta_trk, t_trk, x_truth_trk, "
                         "y_truth_trk, theta_truth_trk, detected."),
    overwrite: bool = Switch(False, "Replace existing outputs."),
) -> None:
    """Simulate a robot chain; write its pose log (and optionally a video and a rerun file)."""
    from macrostate_mj.app.usecases.simulate import SimulateRequest, check_request, simulate_run
    from macrostate_mj.chain.scenarios import scenario_for

    req = SimulateRequest(scenario_for(scenario, head_speed), robots, seconds, seed, out, video,
                          rerun, overwrite, track=track, overlays=overlays,
                          video_view=video_view, camera_video=camera_video)
    check_request(req)
    with sim_progress(seconds, "simulating") as advance:
        written = simulate_run(req, advance)
    for kind, path in written.items():
        typer.echo(f"{kind:<9} {path}")
    if track:
        from macrostate_mj.app.usecases.simulate import tracking_summary

        typer.echo(f"tracking  {tracking_summary(written['manifest'])}")


@app.command("export-mjcf")
def export_mjcf(
    scenario: str = Scenario,
    robots: int = Count(5, "Chain length N.", min=2),
    out: Path = OutputFile(..., "Output .xml file.", (".xml",)),
    overwrite: bool = Switch(False, "Replace an existing file."),
) -> None:
    """Write one self-contained MJCF of a scenario with N robots (opens in MuJoCo's viewer)."""
    from macrostate_mj.chain.world import build_world
    from macrostate_mj.core.io import check_writable_file, write_text_atomic

    check_writable_file(out, overwrite, "--out")
    write_text_atomic(out, build_world(scenario, robots).to_xml())
    typer.echo(f"mjcf      {out}")
