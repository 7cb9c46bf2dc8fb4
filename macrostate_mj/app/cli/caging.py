"""`experiment caging`: the caging mission of §2.5.4 with four Tails; `experiment caging-multi`:
two cooperating Tails of one team (§5.2) against one."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from macrostate_mj.app.cli.app import experiment_app
from macrostate_mj.app.cli.experiments import launch
from macrostate_mj.app.cli.params import Choice, Count, OutputDir, Positive, Seed, Switch


@experiment_app.command("caging")
def experiment_caging(
    profile: str = Choice("full", "full: 20 seeds of 90 s, the estimator trained 200 epochs; "
                          "quick: a smoke run (2 seeds, 60 s, 20 epochs).", ("full", "quick")),
    quick: bool = Switch(False, "Shorthand for --profile quick."),
    seeds: int = Count(None, "Episodes per Tail (seeds 0..seeds-1); default: the profile's."),
    time_limit: float = Positive(None, "Simulated seconds per episode; default: the "
                                 "profile's.", max=3600.0),
    epochs: int = Count(None, "Epochs of the ReTLo Tail's three MLPs; default: the "
                        "profile's."),
    seed: int = Seed(0, "Seed of the MLPs' training and the random Tail's draws."),
    out: Path = OutputDir(..., "Output folder."),
    overwrite: bool = Switch(False, "Replace existing outputs (a trained estimator is kept)."),
) -> None:
    """Passive, ReTLo, oracle and random Tails on CagingTail-v0: success rate, time to cage,
    final spacing CV over the seeds, and Fig 2.3-style snapshots."""
    from macrostate_mj.app.experiments import profile as chosen

    given = {"seeds": seeds, "time_limit": time_limit, "epochs": epochs}
    config = replace(chosen("caging", "quick" if quick else profile), seed=seed,
                     **{k: v for k, v in given.items() if v is not None})
    launch("caging", config, out, overwrite)


@experiment_app.command("caging-multi")
def experiment_caging_multi(
    profile: str = Choice("full", "full: 20 seeds of 90 s, the estimators trained 200 epochs; "
                          "quick: a smoke run (2 seeds, 40 s, 20 epochs).", ("full", "quick")),
    quick: bool = Switch(False, "Shorthand for --profile quick."),
    seeds: int = Count(None, "Episodes per arm; default: the profile's."),
    first_seed: int = Seed(0, "The first episode's seed (seeds first..first+seeds-1)."),
    time_limit: float = Positive(None, "Simulated seconds per episode; default: the "
                                 "profile's.", max=3600.0),
    out: Path = OutputDir(..., "Output folder."),
    overwrite: bool = Switch(False, "Replace existing outputs."),
) -> None:
    """Two cooperating scripted Tails of a Head leading two chains against the one Tail of
    `experiment caging`, each fed the Head's true position or a live ReTLo estimate, and the
    two-chain team with passive Tails: success rate, time to cage, paired by seed."""
    from macrostate_mj.app.experiments import profile as chosen

    given = {"seeds": seeds, "time_limit": time_limit}
    config = replace(chosen("caging-multi", "quick" if quick else profile), first_seed=first_seed,
                     **{k: v for k, v in given.items() if v is not None})
    launch("caging-multi", config, out, overwrite)
