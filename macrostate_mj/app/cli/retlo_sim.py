"""`experiment retlo-sim`: the simulation chapter (§2.5) on the robotarium scenario."""

from __future__ import annotations

import time
from pathlib import Path

import typer

from macrostate_mj.app.cli.app import experiment_app
from macrostate_mj.app.cli.params import Count, OutputDir, Seed, Switch
from macrostate_mj.core.progress import stage_progress


@experiment_app.command("retlo-sim")
def experiment_retlo_sim(
    out: Path = OutputDir(..., "Output folder (case_*.png, results.json, manifest)."),
    seed: int = Seed(0, "Seed of every random draw (noise, weights, batches)."),
    epochs: int = Count(500, "Number of training epochs of the three networks (section "
                        "2.5.2.1)."),
    train_steps: int = Count(800, "Steps (30 Hz ticks) per training treatment.", max=10**6),
    test_steps: int = Count(1600, "Steps (30 Hz ticks) per test case.", max=10**6),
    overwrite: bool = Switch(False, "Replace existing outputs."),
) -> None:
    """Fig 2.2: chained MLPs trained on 3 robots, estimating 5- and 6-robot chains."""
    from macrostate_mj.app.experiments.retlo_sim import (
        PRODUCTS,
        SimExperimentConfig,
        run_experiment,
    )
    from macrostate_mj.core.io import prepare_out_dir

    cfg = SimExperimentConfig(seed=seed, epochs=epochs, train_steps=train_steps,
                              test_steps=test_steps)
    cfg.validate()
    prepare_out_dir(out, PRODUCTS, overwrite)
    out.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    with stage_progress() as progress:
        lines = run_experiment(cfg, out, progress)
    for line in lines:
        typer.echo(line)
    typer.echo(f"took {time.perf_counter() - start:.0f} s")
