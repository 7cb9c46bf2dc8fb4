"""`experiment srs`: chapter 3 (SRS) end to end on simulated data."""

from __future__ import annotations

from pathlib import Path

import typer

from macrostate_mj.app.cli.app import experiment_app
from macrostate_mj.app.cli.params import MAX_WORKERS, Count, OutputDir, Seed, Switch


@experiment_app.command("srs")
def experiment_srs(
    quick: bool = Switch(False, "A smoke profile (small datasets, one of each, few epochs) "
                         "instead of Table 3.1's sizes with 3 datasets and 3 models each."),
    seed: int = Seed(0, "Experiment seed; dataset j of every configuration uses seed*1000+j."),
    workers: int = Count(1, "Local worker processes (collections and trainings).",
                         max=MAX_WORKERS),
    ray: str = typer.Option(None, "--ray", help="Run tasks on Ray: local, auto or ADDRESS."),
    out: Path = OutputDir(..., "Output folder (datasets and models are cached in it)."),
    overwrite: bool = Switch(False, "Replace the figures and results (cached tasks are kept; "
                             "delete the folder to start over)."),
) -> None:
    """Table 3.1, Fig 3.4 (σ sweep), Fig 3.5a/b (policies over budgets), Fig 3.6 (step-wise,
    5 robots) and Fig 3.7 (distance histograms); resumes after an interruption."""
    from macrostate_mj.app.experiments.srs import PRODUCTS, SRSProfile, run_srs_experiment
    from macrostate_mj.core.io import prepare_out_dir

    prepare_out_dir(out, PRODUCTS, overwrite)
    profile = SRSProfile.quick() if quick else SRSProfile()
    for line in run_srs_experiment(profile, out, seed, workers, ray):
        typer.echo(line)
