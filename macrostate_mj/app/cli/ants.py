"""`ants simulate`: a simulated H. saltator colony rendered from above and turned into flows."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from macrostate_mj.app.cli.app import ants_app
from macrostate_mj.core.progress import sim_progress

Opt = typer.Option


@ants_app.command("simulate")
def simulate(
    out: Annotated[Path, Opt(help="Output folder (flows/, labels.csv, boxes.csv, manifest).")],
    ants: Annotated[int, Opt(help="Number of ants in the nest.")] = 55,
    days: Annotated[str, Opt(help="Day range (D-2..D+18) or list (D-1,D+1,D+9).")] = "D-2..D+18",
    seconds_per_day: Annotated[float, Opt(help="Simulated seconds per day.")] = 60.0,
    fps: Annotated[float, Opt(help="Frame rate of the overhead camera.")] = 15.0,
    size: Annotated[int, Opt(help="Side of the square overhead frames (px).")] = 256,
    seed: Annotated[int, Opt(help="Seed of every random draw (per day: seed, day).")] = 0,
    prey: Annotated[int, Opt(help="Number of passive prey items (crickets).")] = 0,
    video: Annotated[bool, Opt("--video", help="Also write video/D±N.mp4 per day.")] = False,
    frames: Annotated[bool, Opt("--frames", help="Also write frames/D±N/*.jpg per day.")] = False,
    every: Annotated[float, Opt(help="Seconds between flow samples.")] = 2.0,
    gap: Annotated[float, Opt(help="Seconds between the two frames of a flow pair.")] = 0.5,
    m: Annotated[int, Opt(help="Flow pairs per sample.")] = 4,
    method: Annotated[str, Opt(help="Flow method: dis, farneback or tvl1.")] = "dis",
    overwrite: Annotated[bool, Opt("--overwrite", help="Replace earlier outputs.")] = False,
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
