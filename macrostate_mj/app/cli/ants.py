"""`ants simulate`: a simulated H. saltator colony rendered from above and turned into flows."""

from __future__ import annotations

from pathlib import Path

import typer

from macrostate_mj.app.cli.app import ants_app
from macrostate_mj.app.params import (
    MAX_SECONDS,
    Choice,
    Count,
    OutputDir,
    Positive,
    Seed,
    Switch,
)
from macrostate_mj.core.progress import sim_progress
from macrostate_mj.vision.flow import METHODS as FLOW_METHODS


@ants_app.command("simulate")
def simulate(
    out: Path = OutputDir(..., "Output folder (flows/, labels.csv, boxes.csv, manifest)."),
    ants: int = Count(55, "Number of ants in the nest.", min=1, max=80),
    days: str = typer.Option("D-2..D+18", help="Day range (D-2..D+18) or list (D-1,D+1,D+9)."),
    seconds_per_day: float = Positive(60.0, "Simulated seconds per day.", max=MAX_SECONDS),
    fps: float = Positive(15.0, "Frame rate of the overhead camera.", max=60),
    size: int = Count(256, "Side of the square overhead frames (px), a multiple of 8.",
                      min=32, max=1024),
    seed: int = Seed(0, "Seed of every random draw (per day: seed, day)."),
    prey: int = Count(0, "Number of passive prey items (crickets).", min=0, max=10),
    video: bool = Switch(False, "Also write video/D±N.mp4 per day (annotated: day, clock, "
                         "true duel and bite boxes).", "--save-video/--no-save-video"),
    frames: bool = Switch(False, "Also write frames/D±N/*.jpg per day (raw, for `flow "
                          "--frames`).", "--save-frames/--no-save-frames"),
    every: float = Positive(2.0, "Seconds between flow samples."),
    gap: float = Positive(0.5, "Seconds between the two frames of a flow pair."),
    m: int = Count(4, "Flow pairs per sample written (the dataset's sub-frames; `oc --m` "
                   "uses up to this many)."),
    method: str = Choice("dis", "Optical-flow method.", FLOW_METHODS),
    overwrite: bool = Switch(False, "Replace earlier outputs."),
) -> None:
    """Simulate the colony day by day (stable D-2..D-1, unstable after the removal) and write
    its optical-flow dataset in the OpticalFlows_HsAnts layout, labels and duel/bite boxes."""
    from collectors.colony_days import ColonyRequest, simulate_colony, validate

    req = ColonyRequest(out, ants, days, seconds_per_day, fps, size, seed, prey, video, frames,
                        every, gap, m, method, overwrite)
    total = len(validate(req)) * seconds_per_day
    with sim_progress(total, "simulating colony") as advance:
        written = simulate_colony(req, advance)
    for kind, path in written.items():
        typer.echo(f"{kind:<14} {path}")
