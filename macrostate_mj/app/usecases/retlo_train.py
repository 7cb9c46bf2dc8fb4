"""`train retlo` and `calibrate retlo` as use cases: the checks, the run in its folder (a
manifest beside the checkpoint, `<out>.manifest.json`) and the checkpoint; the command only
parses flags and prints."""

from __future__ import annotations

from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

from macrostate_mj.core.errors import UserError
from macrostate_mj.core.io import check_writable_file
from macrostate_mj.core.run import Run


class TrainingInterrupted(KeyboardInterrupt):
    """Ctrl-C during training: the best checkpoint so far is saved and the run's manifest says
    `interrupted`; `info` is the training record up to there."""

    def __init__(self, info: dict):
        super().__init__()
        self.info = info


@dataclass(frozen=True)
class TrainRequest:
    cfg: Any                    # estimators.retlo.train.TrainConfig
    uncertainty: str            # a name of estimators.retlo.UNCERTAINTIES
    train: tuple[Path, ...]
    val: Path
    out: Path
    px_per_cm: float
    init: Path | None = None    # a checkpoint to fine-tune
    mix: tuple[Path, ...] = ()
    mix_weight: float = 0.5
    overwrite: bool = False


def train(req: TrainRequest) -> dict:
    """Train (or fine-tune) one module and save its best validation checkpoint; the training
    record. Bad input, a mismatched `init` included, is refused before the folder is touched;
    an interrupted training keeps its best checkpoint and raises `TrainingInterrupted`."""
    from estimators.retlo.api import fit
    from estimators.retlo.files import read_world
    from estimators.retlo.heads import head_named
    from estimators.retlo.train import load_checkpoint, save_checkpoint

    cfg = req.cfg
    if cfg.frozen and req.init is None:
        raise UserError("--freeze-encoder fine-tunes a model: pass --init MODEL.pt too")
    head = head_named(req.uncertainty)     # the one place the name becomes an object
    start = None
    if req.init is not None:
        start, _ = load_checkpoint(req.init)
        if start.cfg != cfg.model:
            raise UserError(f"--init {req.init} is a different model from the one the flags "
                            f"ask for ({_differences(start.cfg, cfg.model)}); pass its settings")
        if start.head != head:
            raise UserError(f"--init {req.init} has uncertainty {start.head.name}, not "
                            f"{head.name}; pass --uncertainty {start.head.name}")
    check_writable_file(req.out, req.overwrite, "--out")
    with Run(req.out.parent, "train retlo", cfg, cfg.seed, [req.out.name], req.overwrite,
             manifest=req.out.name + ".manifest.json") as run:
        worlds = [read_world(p, req.px_per_cm) for p in req.train]
        val_world = read_world(req.val, req.px_per_cm)
        with run.stage("train"):
            net, info = fit(worlds, val_world, cfg, progress=True, init=start,
                            mix=[read_world(p, req.px_per_cm) for p in req.mix],
                            mix_weight=req.mix_weight, head=head)
        save_checkpoint(req.out, net, req.px_per_cm, cfg, info)
        run.record(inputs=[str(p) for p in [*req.train, req.val]],
                   init=str(req.init) if req.init else None,
                   mix=[str(p) for p in req.mix], mix_weight=req.mix_weight if req.mix else None,
                   **({"uncertainty": head.name} if head.uncertain else {}))
        if info["interrupted"]:
            raise TrainingInterrupted(info)
    return info


def _differences(have: object, want: object) -> str:
    """`name: have -> want` of every field two model configs disagree on."""
    return ", ".join(f"{f.name}: it has {getattr(have, f.name)!r}, not {getattr(want, f.name)!r}"
                     for f in fields(have) if getattr(have, f.name) != getattr(want, f.name))


def calibrate(model: Path, val: Path, out: Path, seed: int, px_per_cm: float,
              overwrite: bool = False) -> dict:
    """A Gaussian checkpoint's uncertainty refitted on `val`, saved to `out` (the same
    weights); the fitted record."""
    from estimators.retlo.files import read_world
    from estimators.retlo.train import load_checkpoint, save_recalibrated

    check_writable_file(out, overwrite, "--out")
    net, ckpt = load_checkpoint(model)
    with Run(out.parent, "calibrate retlo", {"model": str(model), "val": str(val),
                                             "px_per_cm": px_per_cm}, seed, [out.name],
             overwrite, manifest=out.name + ".manifest.json") as run:
        with run.stage("calibrate"):
            record = save_recalibrated(out, net, ckpt, read_world(val, px_per_cm), seed,
                                       {"file": str(val)})
        run.record(inputs=[str(model), str(val)])
    return record
