"""`collect`: tracked ReTLo datasets from many episodes, in parallel or on Ray."""

from __future__ import annotations

from pathlib import Path

import typer

from macrostate_mj.app.cli.app import app
from macrostate_mj.app.params import (
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
from macrostate_mj.tails.collection import POLICIES
from macrostate_mj.tails.srs import PICKS


@app.command()
def collect(
    scenario: str = Scenario,
    robots: int = Count(3, "Chain length N.", min=2),
    minutes: float = Positive(None, "Simulated driving time, in minutes (passive, random).",
                              max=MAX_SECONDS / 60),
    policy: str = Choice("passive", "The Tail's policy: passive follows the chain rule, random "
                         "adds noise to its destination (Rand-Only), srs runs a Rand-Only phase, "
                         "trains the novelty models on it, then picks among k noisy "
                         "destinations by novelty (dissertation section 3.3).",
                         (*POLICIES, "srs")),
    sigma: float = NonNegative(0.75, "random, srs: noise sigma as a fraction of robot size."),
    srs: str = Choice("max", "srs: which candidate to drive to, by its novelty e: max, the "
                      "upper quartile q3, the median med, the lower quartile q2.", tuple(PICKS)),
    instances: int = Count(None, "srs: instances in all (Rand-Only phase included)."),
    ro_instances: int = Count(100, "srs: instances of the Rand-Only phase.", min=2),
    k: int = Count(30, "srs: candidate destinations per step.", min=2),
    track: bool = Switch(False, "srs: the Tail scores its candidates from the overhead "
                         "tracker's poses (its models learn from tracked data) rather than the "
                         "ground truth."),
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
    randomize: str = typer.Option(None, "--randomize", help="Domain randomization per episode: "
                                  "a profile (wide, wider) or a JSON file of parameter: "
                                  "[low, high] factors (collectors/randomize.py lists the "
                                  "parameters)."),
    keep_unhealthy: bool = Switch(False, "Assemble the datasets even from episodes whose "
                                  "tracking failed the scenario's [tracking] limits (recorded "
                                  "in the manifest); without it such a collection ends with "
                                  "exit 1 and no dataset."),
    overwrite: bool = Switch(False, "Start over, replacing existing outputs."),
) -> None:
    """Collect tracked pose datasets in the ThymioLoc layout; resumes after an interruption."""
    from collectors.runner import CollectRequest, episode_count
    from collectors.runner import collect as run_collect
    from macrostate_mj.chain.scenarios import scenario_for
    from macrostate_mj.core.errors import UserError
    from macrostate_mj.core.progress import sim_progress

    lab = scenario_for(scenario, head_speed)       # the one scenario every episode runs in
    if policy == "srs":
        if instances is None:
            raise UserError("--policy srs needs --instances (the dataset's size, the Rand-Only "
                            "phase included)")
        req = CollectRequest(lab, robots, 0.0, seed, out, "random", sigma, workers, ray,
                             split, overwrite, episode_minutes, px_per_cm=px_per_cm,
                             keep_unhealthy=keep_unhealthy)
        _collect_srs(req, srs, instances, ro_instances, k, track)
        return
    if instances is not None:
        raise UserError(f"--instances is for --policy srs; --policy {policy} takes --minutes")
    if minutes is None:
        raise UserError(f"--policy {policy} needs --minutes (the simulated driving time)")
    req = CollectRequest(lab, robots, minutes, seed, out, policy, sigma, workers, ray,
                         split, overwrite, episode_minutes, px_per_cm=px_per_cm,
                         randomize=randomize, keep_unhealthy=keep_unhealthy)
    episodes = episode_count(req)     # the request is checked once, as the run begins
    with sim_progress(minutes, f"collecting {episodes} episodes", unit="sim min") as bar:
        written = run_collect(req, lambda _, minutes, resumed: bar(minutes, resumed))
    for kind, path in written.items():
        typer.echo(f"{kind:<16} {path}")
    _tracking_line(written)


def _tracking_line(written: dict) -> None:
    """The collection's one-line tracking health, from its manifest."""
    from macrostate_mj.app.usecases.simulate import tracking_summary

    typer.echo(f"{'tracking':<16} {tracking_summary(written['manifest'])}")


def _collect_srs(req, pick: str, instances: int, ro_instances: int, k: int,
                 track: bool) -> None:
    from collectors.srs_collection import SRSRequest, collect_srs
    from estimators.srs.novelty import NoveltyTraining
    from macrostate_mj.core.progress import LoggedProgress

    with LoggedProgress(transient=True) as bar:
        task = bar.add_task("collect srs", total=None)

        def progress(stage: str, done: int, total: int) -> None:
            if bar.tasks[0].description != stage:       # a new stage: its own rate and clock
                bar.reset(task, total=total, description=stage)
            bar.update(task, completed=done, total=total)

        written = collect_srs(SRSRequest(req, pick, instances, ro_instances, k, track),
                              NoveltyTraining(), progress)
    for kind, path in written.items():
        typer.echo(f"{kind:<16} {path}")
    _tracking_line(written)
