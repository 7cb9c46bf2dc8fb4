"""`collect`: tracked ReTLo datasets from many episodes, in parallel or on Ray."""

from __future__ import annotations

from pathlib import Path

import typer

from collectors.policies import POLICIES
from macrostate_mj.app.cli.app import app
from macrostate_mj.app.cli.params import (
    MAX_SECONDS,
    MAX_WORKERS,
    Choice,
    Count,
    NonNegative,
    OutputDir,
    Positive,
    Scenario,
    Seed,
    Switch,
)
from macrostate_mj.formats.thymioloc import DEFAULT_PX_PER_CM


@app.command()
def collect(
    scenario: str = Scenario,
    robots: int = Count(3, "Chain length N.", min=2),
    minutes: float = Positive(..., "Simulated driving time, in minutes.",
                              max=MAX_SECONDS / 60),
    policy: str = Choice("passive", "The Tail's policy: passive follows the chain rule, random "
                         "adds noise to it (SRS, dissertation section 3.3).", POLICIES),
    sigma: float = NonNegative(0.75, "random: noise sigma as a fraction of robot size."),
    seed: int = Seed(0, "Collection seed; each episode derives its own."),
    workers: int = Count(1, "Local worker processes.", max=MAX_WORKERS),
    ray: str = typer.Option(None, "--ray", help="Run episodes on Ray: local, auto or ADDRESS."),
    out: Path = OutputDir(..., "Output folder."),
    split: str = typer.Option(None, help="Also write Train/Val/Test.csv: three percentages "
                              "that sum to 100, e.g. 60/10/30."),
    episode_minutes: float = Positive(5.0, "Driving time per episode (a task)."),
    px_per_cm: float = Positive(DEFAULT_PX_PER_CM, "Pixel scale of the ThymioLoc CSVs."),
    head_speed: float = Positive(None, "Override the scenario's Head speed (m/s), up to the "
                                 "robot's top speed."),
    overwrite: bool = Switch(False, "Start over, replacing existing outputs."),
) -> None:
    """Collect tracked pose datasets in the ThymioLoc layout; resumes after an interruption."""
    from collectors.runner import CollectRequest, plan
    from collectors.runner import collect as run_collect
    from macrostate_mj.core.progress import sim_progress

    req = CollectRequest(scenario, robots, minutes, seed, out, policy, sigma, workers, ray,
                         split, overwrite, episode_minutes, px_per_cm=px_per_cm,
                         head_speed=head_speed)
    episodes = len(plan(req))
    with sim_progress(minutes, f"collecting {episodes} episodes", unit="sim min") as bar:
        written = run_collect(req, lambda done, sim_minutes: bar(sim_minutes))
    for kind, path in written.items():
        typer.echo(f"{kind:<16} {path}")
