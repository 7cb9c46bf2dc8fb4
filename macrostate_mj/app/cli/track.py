"""`track`: the simulator's tracker on a recorded video."""

from __future__ import annotations

from pathlib import Path

import typer

from macrostate_mj.app.cli.app import app
from macrostate_mj.app.params import (
    Count,
    InputFiles,
    OutputDir,
    Positive,
    Scenario,
    Switch,
)
from macrostate_mj.formats.thymioloc import DEFAULT_PX_PER_CM


@app.command()
def track(
    video: Path = InputFiles("The recorded video (e.g. `simulate --camera-video`'s MP4; its "
                             "FILE.times.csv beside it gives the frame times)."),
    scenario: str = Scenario,
    robots: int = Count(..., "Robots in the video (Head, Followers, Tail: the scenario's "
                        "markers, colours or tag ids, in chain order).", min=2),
    out: Path = OutputDir(..., "Output folder (poses.parquet, instances.csv, manifest.json)."),
    px_per_cm: float = Positive(DEFAULT_PX_PER_CM, "Pixel scale of the ThymioLoc CSV."),
    overwrite: bool = Switch(False, "Replace existing outputs."),
) -> None:
    """Track a recorded video with the scenario's camera and tracker into a pose log and
    ThymioLoc instances, as a simulated run's would be."""
    from macrostate_mj.app.track import TrackRequest, check_request, detected_line, track_video
    from macrostate_mj.core.progress import sim_progress

    req = TrackRequest(video, scenario, robots, out, overwrite, px_per_cm)
    _, footage = check_request(req)
    with sim_progress(footage.frames, "tracking", unit="frames") as advance:
        written = track_video(req, advance)
    for kind, path in written.items():
        typer.echo(f"{kind:<9} {path}")
    typer.echo(f"detected  {detected_line(written['manifest'])}")
