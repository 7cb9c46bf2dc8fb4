"""`flow`, `oc train|evaluate`, `experiment oc`: optical flows and one-class models (ch. 4)."""

from __future__ import annotations

from pathlib import Path

import typer

from estimators.oneclass import METHODS
from macrostate_mj.app.cli.app import app, oc_app
from macrostate_mj.app.params import (
    MAX_WORKERS,
    Choice,
    Count,
    Device,
    InputDir,
    InputFile,
    OutputDir,
    OutputFile,
    Positive,
    Precision,
    Seed,
    Switch,
)
from macrostate_mj.core.errors import UserError
from macrostate_mj.core.parallel import torch_threads
from macrostate_mj.core.progress import stage_progress
from macrostate_mj.vision.flow import METHODS as FLOW_METHODS


def _crop(text: str | None) -> tuple[int, int, int, int] | None:
    if text is None:
        return None
    try:
        x, y, w, h = (int(v) for v in text.split(","))
    except ValueError:
        raise UserError(f"--crop {text!r} must be four integers x,y,w,h") from None
    return x, y, w, h


@app.command("flow")
def flow(
    out: Path = OutputDir(..., "Dataset folder to write (OpticalFlows_HsAnts layout)."),
    video: Path = InputFile(None, "Input: any OpenCV-readable video file."),
    frames: Path = InputDir(None, "Input: a folder of frames (natural name order)."),
    every: float = Positive(120.0, "Seconds between samples (the dissertation: 120)."),
    gap: float = Positive(0.5, "Seconds between the two frames of a pair."),
    m: int = Count(4, "Flow pairs per sample written (the dataset's sub-frames; `oc --m` "
                   "uses up to this many)."),
    method: str = Choice("dis", "Optical-flow method (tvl1 needs opencv-contrib).", FLOW_METHODS),
    label: str = Choice(None, "Write into OUT/Stable or OUT/Unstable.", ("Stable", "Unstable")),
    start_id: int = Count(0, "Id of the first sample written.", min=0),
    crop: str = typer.Option(None, help="Crop x,y,w,h (px) before the flow."),
    fps: float = Positive(None, "Frame rate (required with --frames)."),
    overwrite: bool = Switch(False, "Replace samples already there."),
) -> None:
    """Video or frames -> optical-flow samples (flow_x/flow_y/img JPEGs, 64 × 64, 128 = still)."""
    from macrostate_mj.app.usecases.oneclass import flow as run_flow

    target, ids = run_flow(out, video, frames, every, gap, m, method, label, start_id,
                           _crop(crop), fps, overwrite)
    typer.echo(f"wrote {len(ids)} samples ({ids[0]:05d}..{ids[-1]:05d}) to {target}")


@oc_app.command("train")
def oc_train(
    method: list[str] = Choice(..., "The one-class method (docs: explanation/oneclass), or all of "
                               "them; repeat it to train several on shared stages.",
                               (*METHODS, "all")),
    data: Path = InputDir(..., "Dataset folder (Stable/, Unstable/, split1..3/)."),
    out: Path = OutputDir(..., "Model folder to write."),
    split: int = Count(1, "Split 1..3 (its stable train list is the training set).", max=3),
    m: int = Count(2, "Flow pairs per model input, at most the dataset's sub-frames (Table "
                   "4.1's m; the dissertation's best is 2)."),
    seed: int = Seed(),
    recipe: str = Choice("short", "Epoch and step counts: short (for a 2-core CPU) or "
                         "published (the published code's; hours on a CPU).",
                         ("short", "published")),
    epoch_scale: float = Positive(1.0, "Scale every epoch/step count of the recipe "
                                  "(0.05 = quick).", "--epoch-scale"),
    settings: list[str] = typer.Option([], "--set", help="Research: NAME=VALUE on top of the "
                                       "recipe (e.g. cls_epochs=40); repeatable."),
    threads: int = Count(torch_threads(), "torch CPU threads (results repeat for equal "
                         "threads).", max=MAX_WORKERS),
    device: str = Device(),
    precision: str = Precision(),
    overwrite: bool = Switch(False, "Replace an earlier model."),
) -> None:
    """Train a one-class model on stable samples only; model selection on held-out stable data."""
    from estimators.oneclass import OCConfig
    from macrostate_mj.app.usecases.oneclass import train

    methods = tuple(METHODS) if "all" in method else tuple(dict.fromkeys(method))
    cfg = OCConfig.recipe(recipe, m=m, seed=seed, threads=threads, device=device,
                          precision=precision).scaled(epoch_scale).overridden(settings)
    with stage_progress() as tick:                      # stages wait in OUT/stages
        n = train(data, out, methods, cfg, split, recipe, overwrite, tick)
    typer.echo(f"trained {', '.join(methods)} on {n} stable samples -> {out}")


@oc_app.command("evaluate")
def oc_evaluate(
    model: Path = InputDir(..., "Model folder from `oc train`."),
    data: Path = InputDir(..., "Dataset folder."),
    out: Path = OutputFile(..., "Report to write.", (".json",)),
    split: int = Count(1, "Split whose stable test list is scored.", max=3),
    method: str = Choice(None, "Method to score (default: the model's last).", METHODS),
    unstable: Path = InputDir(None, "Score these unstable samples instead of DATA/Unstable "
                              "(a dev set; ids of the full colony, so bins hold)."),
    baseline: str = Choice(None, "Also test the method against this one of the same model "
                           "(paired stratified bootstrap, overall and per bin).", METHODS),
    intervals: bool = Switch(True, "Bootstrap 95 % intervals of every AUC (2,000 resamples)."),
    overwrite: bool = Switch(False, "Replace an earlier report."),
) -> None:
    """AUC of stable test vs unstable samples (unstable = positive), overall and per time bin,
    with bootstrap intervals and, against a baseline, paired p-values."""
    from macrostate_mj.app.usecases.oneclass import evaluate

    report = evaluate(model, data, out, split, method, unstable, baseline, intervals, overwrite,
                      lambda line: typer.echo(line, err=True))
    meth = report["method"]
    ci = report.get("auc_ci95", {}).get("all")
    band = f" [{ci[0]:.3f}, {ci[1]:.3f}]" if ci else ""
    bins_text = ", ".join(f"{k} {v:.3f}" for k, v in report["auc_bins"].items() if v is not None)
    typer.echo(f"{meth}: AUC {report['auc_all']:.3f}{band} ({bins_text}) on "
               f"{report['n_unstable']} unstable -> {out}")
    if baseline is not None:
        vs = report["vs_baseline"]["all"]
        typer.echo(f"  vs {baseline}: {vs['diff']:+.3f} (paired bootstrap p = {vs['p']:.3g})")
