"""`experiment retlo-sim`: the simulation chapter (§2.5) on the robotarium scenario."""

from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

import typer

from macrostate_mj.app.cli.app import experiment_app
from macrostate_mj.app.cli.experiments import launch
from macrostate_mj.app.cli.params import Choice, Count, OutputDir, Seed, Switch


@experiment_app.command("retlo-sim")
def experiment_retlo_sim(
    out: Path = OutputDir(..., "Output folder (case_*.png, results.json, manifest)."),
    profile: str = Choice("full", "full: 500 epochs, 800-step treatments, 1,600-step cases; "
                          "quick: a smoke run (1 epoch, 20 and 40 steps).", ("full", "quick")),
    quick: bool = Switch(False, "Shorthand for --profile quick."),
    seed: int = Seed(0, "Seed of every random draw (noise, weights, batches)."),
    epochs: int = Count(None, "Number of training epochs of the three networks (section "
                        "2.5.2.1); default: the profile's (500)."),
    train_steps: int = Count(None, "Steps (30 Hz ticks) per training treatment; default: the "
                             "profile's (800).", max=10**6),
    test_steps: int = Count(None, "Steps (30 Hz ticks) per test case; default: the profile's "
                            "(1600).", max=10**6),
    overwrite: bool = Switch(False, "Replace existing outputs."),
) -> None:
    """Fig 2.2: chained MLPs trained on 3 robots, estimating 5- and 6-robot chains."""
    from macrostate_mj.app.experiments import profile as chosen

    given = {"epochs": epochs, "train_steps": train_steps, "test_steps": test_steps}
    config = replace(chosen("retlo-sim", "quick" if quick else profile), seed=seed,
                     **{k: v for k, v in given.items() if v is not None})
    start = time.perf_counter()
    launch("retlo-sim", config, out, overwrite)
    typer.echo(f"took {time.perf_counter() - start:.0f} s")
