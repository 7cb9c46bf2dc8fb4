"""Training of a ReTLo network (FC or LSTM) on chains of true poses, and its self-contained
checkpoint.

Samples are every (module, step) of every training instance with the true history (teacher
forcing). Model selection uses what the user will see: the closed-loop chain error on the
validation set, predictions fed back exactly as at test time. Chains come in metres; samples
are in the networks' own units (`models.net_features`), float32.
"""

from __future__ import annotations

import contextlib
import copy
import io
import os
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import torch

from estimators.precision import precision_named
from estimators.retlo import CM_PER_M
from estimators.retlo.chain import (
    Features,
    check_training_chains,
    predict_chain,
    tracks_from_world,
    window,
)
from estimators.retlo.frames import Window, module_targets
from estimators.retlo.gaussian import Regions, mahalanobis2
from estimators.retlo.heads import POINT, Head, head_named
from estimators.retlo.models import ModelConfig, RetloNet, TorchPredictor, net_features
from estimators.retlo.propagate import predict_chain_gaussian, require_uncertain
from estimators.retlo.report import chain_positions, evaluate_chain
from macrostate_mj.core.checks import check_count, check_positive, check_seed
from macrostate_mj.core.errors import UserError
from macrostate_mj.core.io import atomic_path

FORMAT = "macrostate-mj/retlo-checkpoint"
VERSION = 1


@dataclass(frozen=True)
class TrainConfig:
    """Optimisation settings; the defaults converge in about a minute or two on one core."""

    epochs: int = 60
    patience: int = 20  # epochs without a better validation error before stopping
    batch: int = 64
    lr: float = 2e-3  # start of a cosine decay to 0 over `epochs`: converges in fewer epochs
    angle_weight: float = 1.0  # angle MAE (rad) against position error (spacing units)
    seed: int = 0
    threads: int = 1  # one thread: bit-identical results, and fair to a shared machine
    feedback: bool = True  # also train on the model's own fed-back predictions (see `train`)
    chained: bool = True   # and with the Follower seen as a chained module sees it (see below)
    mirror: bool = True  # reflect a random half of every batch (see `mirror_signs`)
    model: ModelConfig = field(default_factory=ModelConfig)
    frozen: tuple[str, ...] = ()   # parameter-name prefixes kept fixed (fine-tuning: ENCODER)
    precision: str = "fp32"   # the training forward passes' arithmetic (`estimators.precision`)

    def __post_init__(self) -> None:
        precision = precision_named(self.precision)
        if precision.dtype is not None:      # refused here, before a run collects or loads
            precision.check_runs(RetloNet(self.model, 1.0))
        for name in ("epochs", "patience", "batch", "threads"):
            check_count(getattr(self, name), name)
        check_seed(self.seed)
        check_positive(self.lr, "lr")
        check_positive(self.angle_weight, "angle_weight", zero=True)

    def autocast(self) -> contextlib.AbstractContextManager:
        """Where a training forward pass runs; its outputs are cast to float32 for the loss."""
        return precision_named(self.precision).context()


ENCODER = ("f_obs.", "f_hist.")    # what a fine-tuning may freeze: the observation and history
#                                    encoders, leaving the fusion layer and the heads to train


def _append(parts: dict[str, list[np.ndarray]], x: Features, truth: np.ndarray, k: int, t: int,
            win: Window) -> None:
    """One step's network inputs and its eq. 2.4 targets from true poses (B, S, N, 3), Tail
    first, in the step's frame (positions in cm, as the inputs)."""
    pos, ang = module_targets(truth[:, t, k + 2], truth[:, t, k + 1], truth[:, t + 1, k + 1],
                              win.origin, win.alpha)
    for key, val in zip(("obs", "hist", "pos", "ang"), (*x, pos * CM_PER_M, ang), strict=True):
        parts.setdefault(key, []).append(val)


def make_samples(worlds: list[np.ndarray], cfg: ModelConfig) -> dict[str, np.ndarray]:
    """Every module and step of every chain, with true history: obs, hist, pos, ang arrays."""
    parts: dict[str, list[np.ndarray]] = {"obs": [], "hist": [], "pos": [], "ang": []}
    for world in worlds:
        truth = world[:, :, ::-1]  # Tail first
        tracks = tracks_from_world(truth, world.shape[1])   # all history true
        for k in range(world.shape[2] - 2):
            for t in range(cfg.history, world.shape[1] - 1):
                win = window(tracks, k, t, cfg.history, cfg.rotate)
                _append(parts, net_features(win, cfg), truth, k, t, win)
    return {k: np.concatenate(v).astype(np.float32) for k, v in parts.items()}


def mirror_signs(cfg: ModelConfig) -> dict[str, np.ndarray]:
    """Per-feature signs that reflect a sample across the frame's x axis: y → -y, θ → -θ.

    The motion rules of §2.3 have no left or right, so a reflected chain is as plausible as the
    original: training flips a random half of every batch, doubling the turns the model sees at
    no cost. With cos/sin angles only the sine flips.
    """
    ang = [1.0, -1.0] if cfg.cos_sin else [-1.0]
    hist = [1.0, -1.0, *ang] * 2 + ([1.0] if cfg.mark_estimates else [])
    return {"obs": np.array([1.0, -1.0, 1.0, -1.0]), "hist": np.array(hist),
            "pos": np.array([1.0, -1.0]), "ang": np.array([-1.0, -1.0, -1.0])}


def mean_spacing(worlds: list[np.ndarray]) -> float:
    """Mean neighbour distance (in the worlds' unit): the position scale the network works in."""
    return float(np.mean(np.concatenate([np.linalg.norm(np.diff(w[..., :2], axis=2), axis=-1)
                                         .ravel() for w in worlds])))


def errors(pos: torch.Tensor, ang: torch.Tensor, batch: dict[str, torch.Tensor],
           pos_scale: torch.Tensor, cos_sin: bool, head: Head = POINT
           ) -> tuple[torch.Tensor, torch.Tensor]:
    """The loss's terms per sample (§2.6.2.3): the head's position term in spacing units (the
    Euclidean error of a point, the NLL of a Gaussian) and the absolute error of each angle
    output (radians wrapped, or cos/sin)."""
    pos_err = head.position_loss(pos, batch["pos"] / pos_scale, batch.get("mean_only"))
    if cos_sin:
        target = torch.stack([torch.cos(batch["ang"]), torch.sin(batch["ang"])], dim=-1)
        return pos_err, (ang - target).abs()
    return pos_err, (torch.remainder(ang - batch["ang"] + torch.pi, 2 * torch.pi)
                     - torch.pi).abs()


def _loss(net: RetloNet, batch: dict[str, torch.Tensor], cfg: TrainConfig) -> torch.Tensor:
    """Euclidean position error (in spacing units) + angle MAE, as §2.6.2.3 prescribes; with
    per-sample weights `batch["w"]` (mixed data), their weighted mean."""
    with cfg.autocast():
        pos, ang = net(batch["obs"], batch["hist"])
    pos, ang, angle_weight = pos.float(), ang.float(), cfg.angle_weight
    pos_err, ang_err = errors(pos, ang, batch, net.pos_scale, net.cfg.cos_sin, net.head)
    if "w" in batch:
        w = batch["w"]
        per = pos_err + angle_weight * ang_err.reshape(len(w), -1).mean(dim=1)
        return (w * per).sum() / w.sum()
    return pos_err.mean() + angle_weight * ang_err.mean()


def as_chained(world: np.ndarray, est: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """The chains as module k >= 1 of a longer chain sees them: there the Follower is the
    previous module's Head estimate, so after τ its track carries that estimate's error. Each
    instance's Follower gets the Head-estimate error of another instance (time-aligned), the
    targets stay true. Without this, 3-robot training never shows a module an estimated
    Follower, and FC, which reads the Follower's motion, amplifies the error module after
    module (Head error 3x the 2X heuristic's on 5-robot chains)."""
    err = est[:, :, 0, :2] - world[:, :, 0, :2]        # (B, S, 2); NaN before τ and at the end
    err = np.nan_to_num(err[rng.permutation(len(world))])
    out = world.copy()
    out[:, :, 1, :2] += err
    return out


def _predict_recorded(net: RetloNet, world: np.ndarray, samples: dict[str, list[np.ndarray]]
                      ) -> np.ndarray:
    """`predict_chain`, adding every step's inputs and true targets (from `world`) to samples."""
    truth = world[:, :, ::-1]
    return predict_chain(TorchPredictor(net), world,
                         lambda k, t, x, win: _append(samples, x, truth, k, t, win))


def _with_feedback(net: RetloNet, worlds: list[np.ndarray], data: dict[str, torch.Tensor],
                   chained: bool, rng: np.random.Generator,
                   weights: list[float] | None = None) -> dict[str, torch.Tensor]:
    """Add the samples the current model would meet at test time: histories holding its own
    fed-back predictions, frames built from its own estimates, paired with the true targets.
    Teacher forcing alone leaves the LSTM blind to its own drift (errors grow step after step);
    this is DAgger-style data aggregation, refreshed every epoch.

    With an uncertain head (`data` then has "mean_only"), the chained samples train its mean
    only: their Follower carries an upstream estimate's error, which the chain's Monte Carlo
    (`propagate`) adds itself; learnt into the covariance too it would count twice, and make
    every module underconfident (on the known-noise case of `tests/estimators/
    test_uncertainty.py`, σ 4.0 cm predicted for 3.0 cm true)."""
    samples: dict[str, list[np.ndarray]] = {}
    for j, world in enumerate(worlds):
        before = sum(len(a) for a in samples.get("obs", []))
        est = _predict_recorded(net, world, samples)
        if "mean_only" in data:
            own = sum(len(a) for a in samples["obs"]) - before
            samples.setdefault("mean_only", []).append(np.zeros(own))
        if chained:
            at = sum(len(a) for a in samples["obs"])
            _predict_recorded(net, as_chained(world, est, rng), samples)
            if "mean_only" in data:
                samples["mean_only"].append(np.ones(sum(len(a) for a in samples["obs"]) - at))
        if weights is not None:      # this file's samples keep its weight
            added = sum(len(a) for a in samples["obs"]) - before
            samples.setdefault("w", []).append(np.full(added, weights[j]))
    extra = {k: torch.from_numpy(np.concatenate(v).astype(np.float32)) for k, v in samples.items()}
    return {k: torch.cat([data[k], extra[k]]) for k in data}


def _train_epoch(net: RetloNet, opt: torch.optim.Optimizer, data: dict[str, torch.Tensor],
                 signs: dict[str, torch.Tensor], rng: np.random.Generator, cfg: TrainConfig,
                 ) -> tuple[float, int]:
    """One pass over shuffled mini-batches (mirrored at random): summed loss, batches run."""
    net.train()
    n = len(data["obs"])
    order = torch.from_numpy(rng.permutation(n))
    total, batches = 0.0, 0
    for i in range(0, n, cfg.batch):
        idx = order[i:i + cfg.batch]
        batch = {k: v[idx] for k, v in data.items()}
        if cfg.mirror:
            flip = torch.from_numpy(rng.random(len(idx)) < 0.5)
            batch = {k: torch.where(flip.view(-1, *[1] * (v.dim() - 1)), v * signs[k], v)
                     if k in signs else v for k, v in batch.items()}
        loss = _loss(net, batch, cfg)
        opt.zero_grad()
        loss.backward()
        opt.step()
        total += float(loss.detach()) * len(idx)
        batches += 1
    return total, batches


def train(train_worlds: list[np.ndarray], val_world: np.ndarray, cfg: TrainConfig,
          progress: bool = True, on_epoch: Callable[[int, float], None] | None = None,
          init: RetloNet | None = None, shares: list[float] | None = None,
          head: Head = POINT) -> tuple[RetloNet, dict]:
    """Train with Adam on chains (B, S, N, 3) in metres, file order; keep the best closed-loop
    validation checkpoint, stop early.

    `init`: fine-tune a copy of this network (its sizes and spacing scale) instead of a fresh
    one; `cfg.model` must describe it, and `cfg.frozen` names the parameters kept fixed.
    `shares`: per training file, its share of the loss (mixing sim and real data): each of its
    samples weighs the share over the file's sample count; None weighs every sample alike.
    `head`: the position output (`heads`); a Gaussian one is trained on its NLL, and model
    selection stays on the closed-loop error of its mean (what a point model is chosen by).

    `progress` shows a bar of its own; a caller with its own bar passes `on_epoch(epoch, val_cm)`.
    Ctrl-C after the first validated epoch stops training and returns the best checkpoint so
    far, with `info["interrupted"]` set (before it, the interrupt propagates).
    """
    for i, w in enumerate(train_worlds):
        check_training_chains(w, cfg.model.history, what=f"training file {i + 1}")
    check_training_chains(val_world, cfg.model.history, what="validation file")
    if init is not None and init.cfg != cfg.model:
        raise UserError(f"the initial model is a {_describe(init.cfg)}, not the "
                        f"{_describe(cfg.model)} asked for; pass the model's own settings")
    if init is not None and init.head != head:
        raise UserError(f"the initial model has uncertainty {init.head.name!r}, not the "
                        f"{head.name!r} asked for; pass --uncertainty {init.head.name}")
    if shares is not None and (len(shares) != len(train_worlds)
                               or not all(np.isfinite(s) and s > 0 for s in shares)):
        raise UserError("shares must be one positive number per training file")
    torch.set_num_threads(cfg.threads)
    torch.manual_seed(cfg.seed)
    rng = np.random.default_rng(cfg.seed)
    weights = None
    if shares is None:
        base = make_samples(train_worlds, cfg.model)
    else:
        parts = [make_samples([w], cfg.model) for w in train_worlds]
        weights = [s / len(p["obs"]) for s, p in zip(shares, parts, strict=True)]
        base = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
        base["w"] = np.concatenate([np.full(len(p["obs"]), wt, np.float32)
                                    for p, wt in zip(parts, weights, strict=True)])
    if head.uncertain:      # which samples train the mean only (see `_with_feedback`)
        base["mean_only"] = np.zeros(len(base["obs"]), np.float32)
    signs = {k: torch.from_numpy(v).float() for k, v in mirror_signs(cfg.model).items()}
    net = (RetloNet(cfg.model, CM_PER_M * mean_spacing(train_worlds), head) if init is None
           else copy.deepcopy(init).train())
    for name, p in net.named_parameters():
        p.requires_grad_(not name.startswith(cfg.frozen) if cfg.frozen else True)
    opt = torch.optim.Adam([p for p in net.parameters() if p.requires_grad], lr=cfg.lr)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, T_max=cfg.epochs)
    best = (float("inf"), -1, copy.deepcopy(net.state_dict()))
    curve: list[dict] = []
    batches = 0
    start = time.perf_counter()
    from macrostate_mj.core.progress import LoggedProgress

    with LoggedProgress(disable=not progress, transient=True) as bar:
        task = bar.add_task(f"train {cfg.model.kind}", total=cfg.epochs)
        interrupted = False
        try:
            for epoch in range(cfg.epochs):
                data = {k: torch.from_numpy(v) for k, v in base.items()}
                if cfg.feedback:
                    data = _with_feedback(net, train_worlds, data, cfg.chained, rng, weights)
                n = len(data["obs"])
                total, done = _train_epoch(net, opt, data, signs, rng, cfg)
                batches += done
                sched.step()
                val_cm = evaluate_chain(TorchPredictor(net), val_world)["mean_error_cm"]
                curve.append({"epoch": epoch, "train_loss": total / n, "val_cm": val_cm})
                if val_cm < best[0]:
                    best = (val_cm, epoch, copy.deepcopy(net.state_dict()))
                bar.update(task, advance=1, description=f"train {cfg.model.kind} epoch {epoch + 1} "
                           f"val {val_cm:.2f} cm (best {best[0]:.2f} @ {best[1] + 1})")
                if on_epoch is not None:
                    on_epoch(epoch, val_cm)
                if epoch - best[1] >= cfg.patience:
                    break
        except KeyboardInterrupt:
            if best[1] < 0:
                raise
            interrupted = True
    net.load_state_dict(best[2])
    net.eval()
    info = {"best_val_cm": best[0], "best_epoch": best[1] + 1, "epochs_run": len(curve),
            "train_seconds": time.perf_counter() - start, "n_samples": len(base["obs"]),
            "batches": batches, "interrupted": interrupted,
            "curve": curve}
    if head.uncertain:
        net.cov_scale, net.regions = recalibrate(net, val_world, cfg.seed)
        info["cov_scale"] = net.cov_scale
        info["region_radius2"] = net.regions.summary()
    return net, info


def recalibrate(net: RetloNet, val_world: np.ndarray, seed: int) -> tuple[float, Regions]:
    """The factor s² on every covariance that maximises the likelihood of the validation chains,
    closed loop as at test time: s² = mean Mahalanobis² / 2 (2-D); and the radii of the p-regions,
    the quantiles of those chains' Mahalanobis² under s²Σ (`gaussian.Regions`: what places the 50 %
    and the 90 % region both). Why: Σ is fitted on training samples, whose errors a network drives
    below those it makes on new chains, so it comes out overconfident (real 3-robot LSTM, held-out
    instances: 72-74 % inside its 90 % region before the scale, 85-88 % after, measured when it was
    added); one scalar fitted on the set that already selects the checkpoint corrects the scale and
    keeps Σ's shape (Kuleshov et al. 2018; Levi et al. 2019). The real errors are heavier-tailed
    than a Gaussian, so the likelihood's scale then over-covers the 50 % region (64-68 %): hence the
    radii. They come from the chains that also selected the checkpoint (never the test), so the
    test's coverage is a fair check of them. On chains longer than 3 robots the Monte Carlo
    particles are drawn from the scaled Σ, which moves the later modules' estimates: the radii come
    from a second pass with the scale in place, as the model will then run. Radii are kept per chain
    position (`gaussian.Regions`): 3-robot chains give one, the Head's."""
    net.cov_scale = 1.0
    d2 = _validation_d2(net, val_world, seed)
    scale = float(np.mean(np.concatenate(d2)) / 2)
    if val_world.shape[2] == 3:       # no particles: Mahalanobis² under s²Σ is d2 / s²
        return scale, Regions.fitted(*(d / scale for d in d2))
    net.cov_scale = scale
    return scale, Regions.fitted(*_validation_d2(net, val_world, seed))


def _validation_d2(net: RetloNet, val_world: np.ndarray, seed: int) -> list[np.ndarray]:
    """Mahalanobis² of the finite estimates of the chains (32 Monte Carlo particles), one
    array per chain position (0: the robot module 0 estimates)."""
    est, cov = predict_chain_gaussian(TorchPredictor(net), val_world, 32,
                                      np.random.default_rng(seed))
    n = val_world.shape[2]
    out: list[np.ndarray] = [np.empty(0)] * (n - 2)
    for r, j in enumerate(chain_positions(n)[:n - 2]):    # the estimated robots, file order
        ok = np.isfinite(cov[:, :, r]).all((-1, -2))
        out[j] = mahalanobis2(val_world[:, :, r, :2][ok], est[:, :, r, :2][ok],
                              cov[:, :, r][ok])
    return out


def _describe(cfg: ModelConfig) -> str:
    direction = "" if not cfg.reads_history else (" bidirectional" if cfg.bidirectional
                                                else " unidirectional")
    return (f"{cfg.kind}{direction} model (history {cfg.history}, "
            f"{'cos/sin' if cfg.cos_sin else 'radian'} angles, "
            f"{'rotated' if cfg.rotate else 'compass'} frame)")


def checkpoint_bytes(net: RetloNet, px_per_cm: float, train_cfg: TrainConfig,
                     info: dict) -> bytes:
    """Everything needed to predict: weights, scale, px/cm, config, kind, format and version
    (tensors and plain data: `load_checkpoint` reads it with weights_only). The head's name
    ("uncertainty") is written only for an uncertain head: a point model's bytes stay those of
    the checkpoints written before heads existed, which read back as point models."""
    ckpt = {
        "format": FORMAT, "version": VERSION, "kind": net.cfg.kind,
        "model_config": asdict(net.cfg), "pos_scale_cm": float(net.pos_scale),
        "px_per_cm": float(px_per_cm), "train_config": asdict(train_cfg),
        "train_info": {k: v for k, v in info.items() if k != "train_seconds"},
        "state_dict": net.state_dict(),
    }
    if net.head.uncertain:
        ckpt["uncertainty"] = net.head.name
        ckpt["cov_scale"] = float(net.cov_scale)
        ckpt["region_d2"] = [list(t) for t in net.regions.tables]
    buf = io.BytesIO()
    torch.save(ckpt, buf)
    return buf.getvalue()


def save_checkpoint(path: str | os.PathLike, net: RetloNet, px_per_cm: float,
                    train_cfg: TrainConfig, info: dict) -> Path:
    """`checkpoint_bytes` written atomically to `path`."""
    path = Path(path)
    with atomic_path(path) as tmp:
        tmp.write_bytes(checkpoint_bytes(net, px_per_cm, train_cfg, info))
    return path


def save_recalibrated(path: str | os.PathLike, net: RetloNet, ckpt: dict, val_world: np.ndarray,
                      seed: int, source: dict) -> dict:
    """A loaded Gaussian checkpoint with its covariance scale and region radii refitted on
    `val_world` (`recalibrate`; chains of any length, Monte Carlo from `seed`), written
    atomically to `path`; the weights are untouched. `source` (what the chains were) goes
    into the training record's "calibrated_on". Returns that record."""
    require_uncertain(TorchPredictor(net), "calibrate")
    check_training_chains(val_world, net.cfg.history, what="calibration file")
    net.cov_scale, net.regions = recalibrate(net, val_world, seed)
    record = {**source, "seed": seed, "cov_scale": net.cov_scale,
              "region_radius2": net.regions.summary()}
    ckpt = {**ckpt, "cov_scale": net.cov_scale,
            "region_d2": [list(t) for t in net.regions.tables],
            "train_info": {**ckpt["train_info"], "calibrated_on": record}}
    with atomic_path(Path(path)) as tmp:
        torch.save(ckpt, tmp)
    return record


def load_checkpoint(path: str | os.PathLike) -> tuple[RetloNet, dict]:
    """Load a checkpoint written by `save_checkpoint`, refusing anything else in one line."""
    path = Path(path)
    if path.is_dir():
        raise UserError(f"{path} is a folder, not a checkpoint; pass a .pt from `train retlo` "
                        "or heuristic2x")
    if not path.is_file():
        raise UserError(f"{path}: no such checkpoint; pass a .pt from `train retlo` or heuristic2x")
    try:
        ckpt = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as err:  # torch raises many types for a file that is not its own
        raise UserError(f"{path}: not a readable torch checkpoint ({type(err).__name__}); "
                        "pass a .pt written by `train retlo`") from None
    if not isinstance(ckpt, dict) or ckpt.get("format") != FORMAT:
        raise UserError(f"{path}: not a ReTLo checkpoint; pass a .pt written by `train retlo`")
    if ckpt.get("version") != VERSION:
        raise UserError(f"{path}: ReTLo checkpoint version {ckpt.get('version')}, this code reads "
                        f"{VERSION}; retrain with `train retlo`")
    try:
        head = head_named(ckpt.get("uncertainty", POINT.name))
    except UserError as err:
        raise UserError(f"{path}: {err}; or retrain with `train retlo`") from None
    try:
        cfg = ModelConfig(**ckpt["model_config"])
        net = RetloNet(cfg, ckpt["pos_scale_cm"], head)
        net.load_state_dict(ckpt["state_dict"])
        net.cov_scale = float(ckpt.get("cov_scale", 1.0))
    except (KeyError, TypeError, ValueError, RuntimeError) as err:
        raise UserError(f"{path}: checkpoint does not match the {ckpt.get('kind')} model "
                        f"({type(err).__name__}); retrain with `train retlo`") from None
    if not (np.isfinite(net.cov_scale) and net.cov_scale > 0):
        raise UserError(f"{path}: its covariance scale {net.cov_scale} is not a positive "
                        "number; retrain with `train retlo`")
    try:
        net.regions = Regions.from_record(ckpt.get("region_d2", ()))
    except (TypeError, ValueError) as err:
        raise UserError(f"{path}: {err}; retrain with `train retlo`") from None
    return net.eval(), ckpt
