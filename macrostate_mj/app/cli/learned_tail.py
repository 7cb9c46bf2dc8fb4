"""`experiment learned-tail`: a Tail that learns (PPO) to move so that its frozen estimator
localizes the Head well (§5.2), against scripted Tails."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from macrostate_mj.app.cli.app import experiment_app
from macrostate_mj.app.cli.experiments import launch
from macrostate_mj.app.cli.params import (
    MAX_WORKERS,
    Choice,
    Count,
    InputFileOr,
    OutputDir,
    Positive,
    Seed,
    Switch,
)
from macrostate_mj.app.experiments.learned_tail import POLICIES
from macrostate_mj.env.estimated import HEURISTIC


@experiment_app.command("learned-tail")
def experiment_learned_tail(
    profile: str = Choice("full", "full: 245,760 PPO steps (~35 min on one core), 20 seeds of "
                          "60 s; quick: a smoke run (512 steps, 2 seeds of 20 s).",
                          ("full", "quick")),
    quick: bool = Switch(False, "Shorthand for --profile quick."),
    timesteps: int = Count(None, "PPO timesteps; default: the profile's."),
    seeds: int = Count(None, "Evaluation episodes per Tail (seeds 0..seeds-1, held out from "
                       "training); default: the profile's.", max=500),
    time_limit: float = Positive(None, "Simulated seconds per episode; default: the "
                                 "profile's.", max=3600.0),
    policy: list[str] = Choice(None, "Evaluate only this Tail (repeatable; passive always "
                               "runs, the baseline of the paired test); default all.", POLICIES,
                               "--policy"),
    checkpoint: str = InputFileOr(None, "The Tail's frozen estimator: a ReTLo checkpoint from "
                                  "`train retlo`, or heuristic2x; default the env's trained one "
                                  "(macrostate_mj/assets/models).", (HEURISTIC,), (".pt",)),
    workers: int = Count(1, "Processes for the vector environments (1: all in this one; the "
                         "result does not depend on it).", max=MAX_WORKERS),
    seed: int = Seed(0, "Seed of the PPO training and the random Tail's draws."),
    out: Path = OutputDir(..., "Output folder (a rerun continues training from its last "
                          "checkpoint there)."),
    overwrite: bool = Switch(False, "Replace existing outputs (the trained policy is kept)."),
) -> None:
    """PPO Tail on LocalizeTail-v0 against passive, Rand-Only, SRS-Med and a scripted
    chain-offset Tail: the estimator's Head error over held-out seeds, paired tests against passive,
    spacing, chain breaks, and the learning curve."""
    from macrostate_mj.app.experiments import profile as chosen

    given = {"timesteps": timesteps, "seeds": seeds, "time_limit": time_limit,
             "checkpoint": checkpoint,
             "policies": ("passive", *sorted(set(policy) - {"passive"}, key=POLICIES.index))
             if policy else None}
    config = replace(chosen("learned-tail", "quick" if quick else profile), seed=seed,
                     **{k: v for k, v in given.items() if v is not None})
    launch("learned-tail", config, out, overwrite, workers)
