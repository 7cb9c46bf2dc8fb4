"""`view`: the interactive MuJoCo viewer with the controllers running."""

from __future__ import annotations

import typer

from macrostate_mj.app.cli.app import app
from macrostate_mj.app.params import MAX_SECONDS, Count, Positive, Scenario, Seed


@app.command()
def view(
    scenario: str = Scenario,
    robots: int = Count(5, "Chain length N (Head, N-2 Followers, Tail).", min=2),
    seed: int = Seed(),
    seconds: float = Positive(None, "Close after this many simulated seconds (default: when "
                              "the window is closed).", max=MAX_SECONDS),
    speed: float = Positive(1.0, "Playback speed, a multiple of real time.", max=100),
) -> None:
    """Watch a chain drive in MuJoCo's interactive viewer (needs a display)."""
    from viz.viewer import view as run_view

    reached = run_view(scenario, robots, seed, seconds, speed)
    typer.echo(f"viewed {reached:.1f} simulated s of {scenario.name} with {robots} robots")
