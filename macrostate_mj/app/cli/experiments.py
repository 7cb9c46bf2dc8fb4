"""`experiment list`, and how every `experiment NAME` command launches its run."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import typer

from macrostate_mj.app.cli.app import experiment_app
from macrostate_mj.app.cli.params import MAX_WORKERS, Choice, Count, OutputDir, Precision, Switch
from macrostate_mj.app.experiments.all import MEMBERS


@experiment_app.command("list")
def experiment_list() -> None:
    """Name every experiment with its profiles and what it reproduces."""
    from macrostate_mj.app.experiments import registry

    for name, module in registry().items():
        doc = (module.__doc__ or "").strip().split("\n\n")[0].split(":", 1)[-1]
        typer.echo(f"{name:<10} profiles: {', '.join(module.PROFILES):<22} "
                   f"{' '.join(doc.split())}")


def launch(name: str, config: Any, out: Path, overwrite: bool, workers: int = 1,
           ray: str | None = None) -> None:
    """Run experiment `name` under the run lifecycle with a bar per stage; print its lines."""
    from macrostate_mj.app.experiments import execute
    from macrostate_mj.core.progress import stage_progress

    with stage_progress() as report:
        lines = execute(name, config, out, overwrite, workers, ray, report)
    for line in lines:
        typer.echo(line)


@experiment_app.command("all")
def experiment_all(
    profile: str = Choice("full", "full: the dissertation's sizes, each experiment as the "
                          "docs' committed figures were made; quick: a smoke run of every "
                          "figure.", ("full", "quick")),
    only: list[str] = Choice(None, "Run only this experiment (repeatable); default all.",
                             MEMBERS, "--only"),
    workers: int = Count(1, "Local worker processes for every experiment's tasks.",
                         max=MAX_WORKERS),
    ray: str = typer.Option(None, "--ray", help="Run tasks on Ray: local, auto or ADDRESS."),
    precision: str = Precision(),
    out: Path = OutputDir(..., "Output folder: one sub-folder per experiment, and index.json."),
    overwrite: bool = Switch(False, "Run again after a finished `experiment all` (experiments "
                             "that finished with the same config are kept; delete a "
                             "sub-folder to redo it)."),
) -> None:
    """Every experiment (ReTLo ch. 2, caging, sim-to-real, SRS ch. 3, one-class ch. 4) with one
    profile, each in its own sub-folder; resumes after an interruption; writes index.json.
    Experiments whose real data is absent are skipped and said so."""
    from macrostate_mj.app.experiments.all import Config

    launch("all", Config(profile, tuple(only or ()), precision), out, overwrite, workers, ray)
