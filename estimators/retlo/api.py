"""Fit and evaluate ReTLo's learned modules from ThymioLoc files or world arrays (metres): what
every experiment and command calls, so that none of them repeats the read-train-test sequence.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence

import numpy as np

from estimators.retlo.chain import Module, predict_chain
from estimators.retlo.files import read_world
from estimators.retlo.gaussian import GAUSSIAN_REGIONS
from estimators.retlo.heads import POINT, Head
from estimators.retlo.models import RetloNet
from estimators.retlo.propagate import predict_chain_gaussian, require_uncertain
from estimators.retlo.report import calibration_report, chain_report
from estimators.retlo.train import TrainConfig, train
from macrostate_mj.core.errors import UserError
from macrostate_mj.formats.thymioloc import DEFAULT_PX_PER_CM

Data = str | os.PathLike | np.ndarray   # a ThymioLoc CSV, or chains (B, S, N, 3) in metres


def as_world(data: Data, px_per_cm: float = DEFAULT_PX_PER_CM) -> np.ndarray:
    """Chains in metres from a CSV path, or the array itself."""
    return data if isinstance(data, np.ndarray) else read_world(data, px_per_cm)


def fit(train_data: Sequence[Data], val: Data, cfg: TrainConfig, *,
        px_per_cm: float = DEFAULT_PX_PER_CM, init: RetloNet | None = None,
        mix: Sequence[Data] = (), mix_weight: float = 0.5,
        progress: bool = False, on_epoch: Callable[[int, float], None] | None = None,
        head: Head = POINT) -> tuple[RetloNet, dict]:
    """Train `cfg.model` on the training chains, select and stop early on `val` (see
    `train.train`). `init`: fine-tune a copy of that network (pre-trained on the testbed,
    say). `mix`: more chains (simulated, say) trained on together with the training ones,
    their samples counting `mix_weight` of the loss and the training ones the rest. Returns the
    network and its training record (best validation error in cm, epochs, curve). `head`: a
    point or a Gaussian position output (`heads`)."""
    worlds = [as_world(d, px_per_cm) for d in train_data]
    shares = None
    if mix:
        if not 0.0 < mix_weight < 1.0:
            raise UserError(f"mix_weight must be in (0, 1), the mixed data's share of the "
                            f"loss; got {mix_weight}", "mix_weight")
        extra = [as_world(d, px_per_cm) for d in mix]
        shares = ([(1 - mix_weight) * _share(w, worlds) for w in worlds]
                  + [mix_weight * _share(w, extra) for w in extra])
        worlds += extra
    return train(worlds, as_world(val, px_per_cm), cfg, progress=progress,
                 on_epoch=on_epoch, init=init, shares=shares, head=head)


def _share(world: np.ndarray, group: list[np.ndarray]) -> float:
    """A file's share of its group, by instances."""
    return len(world) / sum(len(w) for w in group)


def predict(module: Module, world: np.ndarray, *, gaussian: bool = False,
            particles: int = 32, seed: int = 0) -> tuple[np.ndarray, np.ndarray | None]:
    """Estimates of chains in metres (`chain.predict_chain`'s layout) and, with `gaussian`,
    their covariances carried along the chain (`propagate`: `particles` Monte Carlo draws
    from `seed`; the estimates are then the mixtures' means). `gaussian` on a point module is
    refused (`propagate.NoUncertaintyError`, a UserError) before any work."""
    if not gaussian:
        return predict_chain(module, world), None
    require_uncertain(module)
    return predict_chain_gaussian(module, world, particles, np.random.default_rng(seed))


def report(module: Module, world: np.ndarray, est: np.ndarray, cov: np.ndarray | None,
           particles: int = 32, seed: int = 0) -> dict:
    """Chapter 3's report (`report.chain_report`, cm) of `predict`'s output; with covariances,
    plus "calibration" per robot and pooled, and the Monte Carlo settings used."""
    out = chain_report(est, world, module.history)
    if cov is None:
        return out
    regions = getattr(module, "regions", GAUSSIAN_REGIONS)
    return {**out, "calibration": calibration_report(est, cov, world, module.history, regions),
            "particles": particles if world.shape[2] > 3 else 1, "seed": seed}


def evaluate(module: Module, data: Data, px_per_cm: float = DEFAULT_PX_PER_CM, *,
             calibrate: bool = False, particles: int = 32, seed: int = 0) -> dict:
    """Chapter 3's report (errors in cm) of a module on chains of any length >= 3; with
    `calibrate`, an uncertain module's calibration too (see `predict`)."""
    world = as_world(data, px_per_cm)
    est, cov = predict(module, world, gaussian=calibrate, particles=particles, seed=seed)
    return report(module, world, est, cov, particles, seed)
