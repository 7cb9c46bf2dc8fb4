"""`collect`: tracked ReTLo datasets from many episodes, in parallel or on Ray."""

from __future__ import annotations

from pathlib import Path

import typer

from macrostate_mj.app.cli.app import app
from macrostate_mj.formats.thymioloc import DEFAULT_PX_PER_CM


@app.command()
def collect(
    scenario: str = typer.Option("lab", help="lab, webots or robotarium."),
    robots: int = typer.Option(3, help="Chain length N."),
    minutes: float = typer.Option(..., help="Simulated driving time, in minutes."),
    policy: str = typer.Option("passive", help="Tail policy: passive or random (SRS §3.3)."),
    sigma: float = typer.Option(0.75, help="random: noise sigma as a fraction of robot size."),
    seed: int = typer.Option(0, help="Collection seed; each episode derives its own."),
    workers: int = typer.Option(1, help="Local worker processes."),
    ray: str = typer.Option(None, "--ray", help="Run episodes on Ray: local, auto or ADDRESS."),
    out: Path = typer.Option(..., help="Output folder."),
    split: str = typer.Option(None, help="Also write Train/Val/Test.csv, e.g. 60/10/30."),
    episode_minutes: float = typer.Option(5.0, help="Driving time per episode (a task)."),
    px_per_cm: float = typer.Option(DEFAULT_PX_PER_CM, help="Pixel scale of the ThymioLoc CSVs."),
    head_speed: float = typer.Option(None, help="Override the scenario's Head speed (m/s)."),
    overwrite: bool = typer.Option(False, help="Start over, replacing existing outputs."),
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
