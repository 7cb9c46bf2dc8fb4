"""`experiment caging`: the caging mission of §2.5.4 with four Tails."""

from __future__ import annotations

from pathlib import Path

import typer

from macrostate_mj.app.cli.app import experiment_app
from macrostate_mj.app.cli.params import Count, OutputDir, Positive, Seed, Switch


@experiment_app.command("caging")
def experiment_caging(
    seeds: int = Count(20, "Episodes per Tail (seeds 0..seeds-1)."),
    time_limit: float = Positive(90.0, "Simulated seconds per episode.", max=3600.0),
    epochs: int = Count(200, "Epochs of the ReTLo Tail's three MLPs."),
    seed: int = Seed(0, "Seed of the MLPs' training and the random Tail's draws."),
    quick: bool = Switch(False, "A smoke run: 2 seeds, 60 s, a briefly trained estimator."),
    out: Path = OutputDir(..., "Output folder."),
    overwrite: bool = Switch(False, "Replace existing outputs (a trained estimator is kept)."),
) -> None:
    """Passive, ReTLo, oracle and random Tails on CagingTail-v0: success rate, time to cage,
    final spacing CV over the seeds, and Fig 2.3-style snapshots."""
    from macrostate_mj.app.experiments.caging import PRODUCTS, CagingExperiment, run_caging
    from macrostate_mj.core.io import prepare_out_dir

    prepare_out_dir(out, PRODUCTS, overwrite)
    cfg = (CagingExperiment(seeds=2, time_limit=60.0, epochs=20, train_steps=300, rehearsals=2,
                            seed=seed)
           if quick else CagingExperiment(seeds, time_limit, epochs, seed=seed))
    for line in run_caging(cfg, out):
        typer.echo(line)
