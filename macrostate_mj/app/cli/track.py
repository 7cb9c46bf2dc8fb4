"""`track`: the simulator's tracker on a recorded video."""

from __future__ import annotations

from pathlib import Path

import typer

from macrostate_mj.app.cli.app import app
from macrostate_mj.app.params import (
    CSV,
    Count,
    InputFile,
    InputFiles,
    OutputDir,
    Positive,
    Scenario,
    Switch,
)
from macrostate_mj.formats.thymioloc import DEFAULT_PX_PER_CM


@app.command()
def track(
    video: Path = InputFiles("The recorded video (e.g. `simulate --camera-video`'s MP4). Frame "
                             "times: each frame's time stamp in the video, checked against "
                             "FILE.times.csv when it is beside it (else against the "
                             "scenario's frame rate)."),
    scenario: str = Scenario,
    robots: int = Count(..., "Robots in the video (Head, Followers, Tail: the scenario's "
                        "markers, colours or tag ids, in chain order).", min=2),
    out: Path = OutputDir(..., "Output folder (poses.parquet, instances.csv, manifest.json)."),
    px_per_cm: float = Positive(DEFAULT_PX_PER_CM, "Pixel scale of the ThymioLoc CSV."),
    times: Path | None = InputFile(None, "The frame times (a frame,t CSV, one row per frame), "
                                   "in place of the video's own and its FILE.times.csv.",
                                   suffixes=CSV),
    fps: float | None = Positive(None, "Frame times of frame index / FPS, in place of the "
                                 "video's own: footage re-encoded at another rate or without "
                                 "its time stamps (right only if no frame was dropped)."),
    overwrite: bool = Switch(False, "Replace existing outputs."),
) -> None:
    """Track a recorded video with the scenario's camera and tracker into a pose log and
    ThymioLoc instances, as a simulated run's would be."""
    from macrostate_mj.app.usecases.track import (
        TrackRequest,
        check_request,
        detected_line,
        track_video,
    )
    from macrostate_mj.core.progress import sim_progress

    req = TrackRequest(video, scenario, robots, out, overwrite, px_per_cm, times, fps)
    checked = check_request(req)
    with sim_progress(checked[1].frames, "tracking", unit="frames") as advance:
        written = track_video(req, advance, checked)
    for kind, path in written.items():
        typer.echo(f"{kind:<9} {path}")
    typer.echo(f"detected  {detected_line(written['manifest'])}")
