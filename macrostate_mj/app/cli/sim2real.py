"""`experiment sim2real`: lab-trained ReTLo models on real data, and the data-efficiency curve."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import typer

from macrostate_mj.app.cli.app import experiment_app
from macrostate_mj.app.cli.experiments import launch
from macrostate_mj.app.cli.params import (
    MAX_SECONDS,
    MAX_WORKERS,
    Chained,
    Choice,
    Count,
    InputDir,
    OutputDir,
    Positive,
    Precision,
    Scenario,
    Seed,
    Switch,
)
from macrostate_mj.app.experiments.sim2real import ARMS, FITS


@experiment_app.command("sim2real")
def experiment_sim2real(
    real: Path = InputDir(None, "Folder of the real ThymioLoc 3-robot Train.csv and Val.csv; "
                          "default: the published ones (`data fetch retlo`)."),
    scenario: str = Scenario,
    sim: Path = InputDir(None, "A lab collection folder (Train.csv, Val.csv) to use instead of "
                         "collecting one (`collect --scenario lab --robots 3 --split 80/20/0`)."),
    randomize: list[str] = typer.Option(None, "--randomize", help="A domain-randomization "
                                        "profile or JSON of factors for the lab collection "
                                        "(e.g. sysid's fitted.json); none by default "
                                        "(`experiment all` runs wider, as the docs' figure). "
                                        "Repeatable: each fold then picks the candidate "
                                        "(`none` for no ranges) whose sim model does best on "
                                        "its own real validation block."),
    sim_minutes: float = Positive(None, "Minutes of lab data to collect (default: the "
                                  "profile's, 100 for full).", "--sim-minutes",
                                  max=MAX_SECONDS / 60),
    profile: str = Choice("full", "full: 5 seeds, 10/25/50/100 % of the real pool; quick: a "
                          "smoke run.", ("full", "quick")),
    quick: bool = Switch(False, "Shorthand for --profile quick."),
    seed: int = Seed(0, "The first model seed: model i trains with seed+i and is tested on real "
                     "fold i mod 5."),
    workers: int = Count(1, "Local worker processes (collection and trainings).",
                         max=MAX_WORKERS),
    ray: str = typer.Option(None, "--ray", help="Run tasks on Ray: local, auto or ADDRESS."),
    arm: list[str] = Choice(None, "Train only this arm (repeatable; default all): `--arm sim` "
                            "asks only how far a lab collection carries.", ARMS, "--arm"),
    fit: list[str] = Choice(None, "Where the lab's factors come from (repeatable: the first "
                            "feeds every arm, each other trains a sim-only model on the same "
                            "folds): none (the scenario as written), train (`sysid` on the "
                            "real Train.csv, which these folds' test blocks are cut from), "
                            "fold (one fit per fold on its training blocks only: the nested "
                            "protocol, what a held-out test will show). With a fit, "
                            "--randomize names the ranges drawn around it.", FITS, "--fit"),
    ablate: list[str] = typer.Option(None, "--ablate", help="Switch these lab parameters "
                                     "off (comma-separated, e.g. frame_hz,frame_jitter; "
                                     "repeatable, one group each): each group trains sim-only "
                                     "models on a lab collected without them, paired with the "
                                     "lab's own over the seeds. Needs --fit or --randomize."),
    chained: bool = Chained,
    fraction: list[float] = Positive(None, "Train the real-data arms on this share of the real "
                                     "pool (repeatable; default: the profile's, 0.1, 0.25, 0.5 "
                                     "and 1 for full).", "--fraction", max=1.0),
    mix_weight: float = Positive(0.5, "The mixed arm: the lab data's share of the loss, in "
                                 "(0, 1).", "--mix-weight", max=1.0),
    precision: str = Precision(),
    out: Path = OutputDir(..., "Output folder (data and models are cached in it)."),
    overwrite: bool = Switch(False, "Replace the figure and results of a finished run (cached "
                             "models and lab data are kept; delete the folder to start over)."),
) -> None:
    """Sim only, real only, sim pre-trained then fine-tuned, and sim and real mixed, on 10-100 %
    of the real data: Head error on held-out real folds (one per seed), the curve and the real
    data saved."""
    from macrostate_mj.app.experiments import profile as chosen
    from macrostate_mj.app.experiments.sim2real import validate
    from macrostate_mj.core.errors import UserError

    base = chosen("sim2real", "quick" if quick else profile)
    config = replace(base, real=real or base.real, sim=sim,
                     scenario=scenario, randomize=tuple(randomize or ()), seed=seed,
                     mix_weight=mix_weight, chained=chained,
                     ablate=tuple(tuple(n.strip() for n in g.split(",") if n.strip())
                                  for g in ablate or ()),
                     precision=precision, fits=tuple(fit or ("none",)),
                     arms=tuple(a for a in ARMS if a in (arm or ARMS)))
    if fraction:
        config = replace(config, fractions=tuple(sorted(set(fraction))))
    if sim_minutes is not None:
        if sim is not None:
            raise UserError("--sim-minutes sizes the lab collection this command makes; drop "
                            "it or --sim")
        config = replace(config, sim_minutes=sim_minutes)
    validate(config)                     # bad input: refused before the folder is claimed
    launch("sim2real", config, out, overwrite, workers, ray)
