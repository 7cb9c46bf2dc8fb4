"""`sysid`: fit a scenario's motion parameters to real ThymioLoc data (summed KS distance)."""

from __future__ import annotations

from pathlib import Path

import typer

from macrostate_mj.app.cli.app import app
from macrostate_mj.app.params import (
    MAX_WORKERS,
    Count,
    InputFile,
    OutputDir,
    Positive,
    Scenario,
    Seed,
    Switch,
)


@app.command("sysid")
def sysid(
    train: Path = InputFile(..., "The real ThymioLoc file the fit minimises the KS sum on.",
                            suffixes=(".csv",)),
    val: Path | None = InputFile(None, "The real file the fit is checked on (default: the "
                                 "last 15 % of --train, which the fit then leaves out, so a "
                                 "sealed test file stays unread).", suffixes=(".csv",)),
    scenario: str = Scenario,
    robots: int = Count(3, "Team size (the real files' own).", min=2, max=12),
    minutes: float = Positive(30.0, "Simulated driving per candidate.", max=10_000.0),
    first: int = Count(16, "Stage-1 candidates over the whole box (the scenario as written is "
                       "one).", min=2),
    refine: int = Count(8, "Stage-2 candidates around stage 1's best.", min=1),
    seed: int = Seed(1, "Collection seed of every candidate, and of the Sobol points."),
    workers: int = Count(1, "Local worker processes per collection.", max=MAX_WORKERS),
    only: list[str] = typer.Option(None, "--only", help="Fit only this parameter (repeatable; "
                                   "e.g. frame_alternation); the others keep the scenario's "
                                   "values."),
    base: str | None = typer.Option(None, "--base", help="Ranges every candidate is drawn "
                                    "within (a --randomize profile or JSON), each around the "
                                    "candidate's factors: fit on top of a recipe's ranges."),
    out: Path = OutputDir(..., "Output folder (candidates are cached in it)."),
    overwrite: bool = Switch(False, "Replace fit.json and fitted.json (cached candidates are "
                             "kept; delete the folder to start over)."),
) -> None:
    """System identification of a scenario (`lab` unless named): gains, speed caps, the wait
    rule's slack and the tracker's noise that make the motion distributions match the real
    Train file (checked on Val)."""
    from macrostate_mj.app.usecases.sysid import CHECK_SHARE, SysidConfig, sysid
    from macrostate_mj.core.progress import LoggedProgress

    cfg = SysidConfig(scenario=scenario, robots=robots, minutes=minutes, seed=seed, first=first,
                      refine=refine, workers=workers, only=tuple(only or ()), base=base)
    with LoggedProgress(transient=True) as bar:
        task = bar.add_task("sysid", total=first + refine)
        report = sysid(cfg, train, val, out, overwrite,
                       lambda done, total: bar.update(task, completed=done))
    checked = val.name if val else f"the last {CHECK_SHARE:.0%} of {train.name}"
    typer.echo(f"summed KS on {train.name}: {report['train']['before']:.3f} -> "
               f"{report['train']['after']:.3f}; on {checked}: {report['val']['before']:.3f} "
               f"-> {report['val']['after']:.3f}")
    typer.echo("fitted factors: " + ", ".join(f"{k} {v:g}" for k, v in report["fitted"].items()))
    typer.echo(f"fit       {out / 'fit.json'}\nprofile   {out / 'fitted.json'} "
               "(collect --randomize)")
