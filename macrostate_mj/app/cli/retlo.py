"""`train retlo`, `evaluate retlo`, `calibrate retlo`: ReTLo models on ThymioLoc data."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import typer

from estimators.retlo import MODEL_KINDS
from macrostate_mj.app.cli.app import calibrate_app, evaluate_app, train_app
from macrostate_mj.app.params import (
    CSV,
    Chained,
    Choice,
    Count,
    History,
    InputFile,
    InputFileOr,
    OutputFile,
    Positive,
    Precision,
    PxPerCm,
    Seed,
    Switch,
    Uncertainty,
)
from macrostate_mj.env.estimated import HEURISTIC

if TYPE_CHECKING:
    from estimators.retlo.chain import Module



@train_app.command("retlo")
def train_retlo(
    model: str = Choice(..., "fc: fully connected layers on the last observations only; "
                        "lstm: the dissertation's model (section 2.6.1.1), an LSTM over the "
                        "history.", MODEL_KINDS),
    train: list[Path] = InputFile(..., "Training ThymioLoc CSV (repeatable).", CSV,
                                  flag="--train"),
    val: Path = InputFile(..., "Validation CSV: selects the checkpoint, stops early.", CSV),
    out: Path = OutputFile(..., "Checkpoint to write.", (".pt",)),
    seed: int = Seed(),
    epochs: int = Count(60, "Number of epochs of the cosine schedule; may stop earlier."),
    patience: int = Count(20, "Epochs without a better validation error to stop."),
    unidirectional: bool = Switch(False, "A unidirectional LSTM (section 3.3 found it as good "
                                  "as the bidirectional one, and faster)."),
    cos_sin: bool = Switch(False, "Angles as cos/sin pairs instead of radians (section 3.3).",
                           "--cos-sin/--radians"),
    compass_frame: bool = Switch(False, "The dissertation's frame (section 2.5.1.1): "
                                 "Tail-centred with compass axes (default: x axis along "
                                 "Tail→Follower)."),
    history: int = History,
    chained: bool = Chained,
    init: Path = InputFile(None, "Fine-tune this checkpoint (from `train retlo`, on simulated "
                           "data say) instead of a fresh network; the model flags must "
                           "describe it.", (".pt",)),
    lr: float = Positive(2e-3, "Adam's learning rate at the start of the cosine schedule "
                         "(fine-tuning with --init: 5e-4 and --epochs 30, the settings the "
                         "sim-to-real recipe measured).", "--lr", max=1.0),
    freeze_encoder: bool = Switch(False, "With --init: keep the observation and history "
                                  "encoders fixed, train the fusion layer and the heads."),
    mix: list[Path] = InputFile(None, "More training chains (simulated, say) trained on "
                                "together with --train (repeatable).", CSV, flag="--mix"),
    mix_weight: float = Positive(0.5, "The --mix data's share of the loss, in (0, 1); --train's "
                                 "is the rest.", "--mix-weight", max=1.0),
    uncertainty: str = Uncertainty,
    px_per_cm: float = PxPerCm,
    precision: str = Precision(),
    overwrite: bool = Switch(False, "Replace an existing checkpoint."),
) -> None:
    """Train a ReTLo module on 3-robot (or longer) chains; keep the best validation checkpoint.
    Sim-to-real: pre-train on testbed data, then fine-tune on your own (--init), or train on
    both at once (--mix)."""
    from estimators.retlo.models import ModelConfig
    from estimators.retlo.train import ENCODER, TrainConfig
    from macrostate_mj.app.usecases.retlo_train import TrainingInterrupted, TrainRequest
    from macrostate_mj.app.usecases.retlo_train import train as run_train

    cfg = TrainConfig(epochs=epochs, patience=patience, seed=seed, chained=chained, lr=lr,
                      frozen=ENCODER if freeze_encoder else (), precision=precision,
                      model=ModelConfig(kind=model, bidirectional=not unidirectional,
                                        cos_sin=cos_sin, rotate=not compass_frame,
                                        history=history))
    try:
        info = run_train(TrainRequest(cfg, uncertainty, tuple(train), val, out, px_per_cm,
                                      init, tuple(mix or ()), mix_weight, overwrite))
    except TrainingInterrupted as stop:      # the best checkpoint so far is saved: say so
        _trained(out, stop.info)
        typer.echo(f"interrupted after epoch {stop.info['epochs_run']}; kept the best "
                   "checkpoint", err=True)
        raise KeyboardInterrupt from None
    _trained(out, info)


def _trained(out: Path, info: dict) -> None:
    typer.echo(f"checkpoint {out}  best validation {info['best_val_cm']:.2f} cm at epoch "
               f"{info['best_epoch']} of {info['epochs_run']} ({info['train_seconds']:.0f} s)")


@evaluate_app.command("retlo")
def evaluate_retlo(
    model: list[str] = typer.Option(..., help="A checkpoint (.pt) from `train retlo`, or "
                                    "heuristic2x; repeat it with Gaussian checkpoints (seeds) "
                                    "to evaluate them as one deep ensemble."),
    first_model: str = InputFileOr(None, "A checkpoint to run as the first module, whose "
                                   "Follower is measured (one trained with --no-chained), "
                                   "--model after it (docs: decisions/chained-training).",
                                   (HEURISTIC,), (".pt",)),
    data: Path = InputFile(..., "ThymioLoc CSV of any chain length >= 3.", CSV),
    out: Path = OutputFile(..., "Report to write.", (".json",)),
    calibration: bool = Switch(None, "Report calibration (coverage of the 50 % and 90 % "
                               "regions, NLL); default: on for models with uncertainty.",
                               "--calibration/--no-calibration"),
    particles: int = Count(32, "Monte Carlo draws carrying uncertainty along chains longer "
                           "than 3 robots.", max=4096),
    seed: int = Seed(0, "Seed of the Monte Carlo draws."),
    video: Path = OutputFile(None, "Also a video of the first instances: truth, estimates and "
                             "their 90 % ellipses.", (".mp4",)),
    rerun: Path = OutputFile(None, "Also a rerun recording of the same.", (".rrd",)),
    px_per_cm: float = PxPerCm,
    overwrite: bool = Switch(False, "Replace an existing report."),
) -> None:
    """Errors (cm) of every robot the Tail cannot see, per robot and per step; for models
    with uncertainty, their calibration."""
    from macrostate_mj.app.usecases.retlo_eval import evaluate_request, outputs_checked

    outputs_checked(out, video, rerun, overwrite)
    module, name = _load_predictor(model)
    if first_model is not None:
        from estimators.retlo.chain import SplitChain

        first, first_name = _load_one(first_model)
        module, name = SplitChain(first, module), f"{name} after {first_name}"
    report = evaluate_request((module, name), data, out, px_per_cm, calibration,
                              particles, seed, video, rerun)
    robots = ", ".join(f"{r} {v:.2f}" if r == report["csv_robot"][r] else
                       f"{r} (CSV {report['csv_robot'][r]}) {v:.2f}"
                       for r, v in report["per_robot_cm"].items())
    typer.echo(f"mean {report['mean_error_cm']:.2f} cm ({robots}) over "
               f"{report['n_instances']} instances -> {out}")
    if "calibration" in report:
        pooled = report["calibration"]["pooled"]
        typer.echo(f"calibration: {pooled['coverage_50']:.2f} inside the 50 % region, "
                   f"{pooled['coverage_90']:.2f} inside the 90 %, NLL {pooled['nll']:.2f}")


@calibrate_app.command("retlo")
def calibrate_retlo(
    model: Path = InputFile(..., "A Gaussian checkpoint from `train retlo --uncertainty "
                            "gaussian`.", (".pt",)),
    val: Path = InputFile(..., "Chains like those it will estimate (any length >= 3, a "
                          "5-robot lab collection say), never the test set: the covariance "
                          "scale and the region radii are fitted on them.", CSV),
    out: Path = OutputFile(..., "Calibrated checkpoint to write (the same weights).", (".pt",)),
    seed: int = Seed(0, "Seed of the Monte Carlo draws along chains longer than 3 robots."),
    px_per_cm: float = PxPerCm,
    overwrite: bool = Switch(False, "Replace an existing checkpoint."),
) -> None:
    """Refit a Gaussian ReTLo model's uncertainty (its covariance scale and the radii of its
    50 %/90 % regions) on other chains, as training does on its validation file: for chains
    unlike that file (longer, another lab) without retraining."""
    from macrostate_mj.app.usecases.retlo_train import calibrate

    record = calibrate(model, val, out, seed, px_per_cm, overwrite)
    radii = "; ".join(f"{r['50%']:.3g} / {r['90%']:.3g}" for r in record["region_radius2"])
    typer.echo(f"checkpoint {out}  covariance scale {record['cov_scale']:.3g}, region radii² "
               f"(50 % / 90 %, per chain position from the Tail's side) {radii}; fitted on "
               f"{val.name}")


def _load_predictor(models: list[str]) -> tuple[Module, str]:
    """`--model` values → predictor and display name: one checkpoint or heuristic2x, or several
    Gaussian checkpoints as one deep ensemble (`estimators.retlo.mixture`)."""
    if len(models) == 1:
        return _load_one(models[0])
    from estimators.retlo.mixture import GaussianEnsemble

    loaded = [_load_one(m) for m in models]
    kinds = sorted({name for _, name in loaded})
    return (GaussianEnsemble([p for p, _ in loaded]),
            f"ensemble of {len(loaded)} {'/'.join(kinds)}")


def _load_one(model: str) -> tuple[Module, str]:
    """A `--model` value (a checkpoint path or heuristic2x) → predictor and display name."""
    from estimators.retlo.heuristic import Heuristic2X
    from estimators.retlo.models import TorchPredictor
    from estimators.retlo.train import load_checkpoint
    from macrostate_mj.core.errors import UserError

    if model == HEURISTIC:
        return Heuristic2X(), HEURISTIC
    if not model.endswith(".pt") and not Path(model).exists():
        raise UserError(f"unknown model {model!r}; pass a checkpoint .pt from `train retlo` "
                        f"or {HEURISTIC}")
    net, ckpt = load_checkpoint(model)
    return TorchPredictor(net), str(ckpt["kind"])
