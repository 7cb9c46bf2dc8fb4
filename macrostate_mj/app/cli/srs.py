"""`experiment srs`: chapter 3 (SRS) end to end on simulated data."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import typer

from macrostate_mj.app.cli.app import experiment_app
from macrostate_mj.app.cli.experiments import launch
from macrostate_mj.app.cli.params import (
    MAX_WORKERS,
    Choice,
    Count,
    OutputDir,
    Precision,
    Seed,
    Switch,
)

PROFILE_NAMES = ("full", "full-seeds", "fig3.5b", "quick")


@experiment_app.command("srs")
def experiment_srs(
    profile: str = Choice("full", "full: the text's protocol, Table 3.1's sizes, every "
                          "configuration, 3 datasets and a model each (Fig 3.5's 3 models); "
                          "full-seeds: the same with 3 model seeds a dataset (9 models a "
                          "cell, as the docs' figures); fig3.5b: Passive, Rand-Only and "
                          "SRS-Med only; quick: a smoke run of every figure.",
                          PROFILE_NAMES),
    quick: bool = Switch(False, "Shorthand for --profile quick."),
    seed: int = Seed(0, "Experiment seed; dataset j of every configuration uses seed*1000+j."),
    workers: int = Count(1, "Local worker processes (collections and trainings).",
                         max=MAX_WORKERS),
    ray: str = typer.Option(None, "--ray", help="Run tasks on Ray: local, auto or ADDRESS."),
    group: int = Count(1, "Models of one shape trained together, this many at a time (for a "
                       "GPU; on a CPU chapter 3's LSTM gains little: `bench --only ensemble`).",
                       max=64),
    precision: str = Precision(),
    out: Path = OutputDir(..., "Output folder (datasets and models are cached in it)."),
    overwrite: bool = Switch(False, "Replace the figures and results of a finished run (cached "
                             "datasets and models are kept; delete the folder to start "
                             "over)."),
) -> None:
    """Table 3.1, Fig 3.4 (σ sweep), Fig 3.5a/b (policies over budgets), Fig 3.6 (step-wise,
    5 robots) and Fig 3.7 (distance histograms); resumes after an interruption."""
    from macrostate_mj.app.experiments import profile as chosen

    config = replace(chosen("srs", "quick" if quick else profile), seed=seed, group=group,
                     precision=precision)
    launch("srs", config, out, overwrite, workers, ray)
