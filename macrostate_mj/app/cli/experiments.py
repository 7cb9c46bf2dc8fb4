"""`experiment list`, and how every `experiment NAME` command launches its run."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import typer

from macrostate_mj.app.cli.app import experiment_app


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
