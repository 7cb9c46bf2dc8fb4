"""Fit and evaluate ReTLo's learned modules from ThymioLoc files or world arrays (metres): what
every experiment and command calls, so that none of them repeats the read-train-test sequence.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence

import numpy as np

from estimators.retlo.chain import Module
from estimators.retlo.files import read_world
from estimators.retlo.models import RetloNet
from estimators.retlo.report import evaluate_chain
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
        ) -> tuple[RetloNet, dict]:
    """Train `cfg.model` on the training chains, select and stop early on `val` (see
    `train.train`). `init`: fine-tune a copy of that network (pre-trained on the testbed,
    say). `mix`: more chains (simulated, say) trained on together with the training ones,
    their samples counting `mix_weight` of the loss and the training ones the rest. Returns the
    network and its training record (best validation error in cm, epochs, curve)."""
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
                 on_epoch=on_epoch, init=init, shares=shares)


def _share(world: np.ndarray, group: list[np.ndarray]) -> float:
    """A file's share of its group, by instances."""
    return len(world) / sum(len(w) for w in group)


def evaluate(module: Module, data: Data, px_per_cm: float = DEFAULT_PX_PER_CM) -> dict:
    """Chapter 3's report (`report.evaluate_chain`, errors in cm) of a module on chains of any
    length >= 3."""
    return evaluate_chain(module, as_world(data, px_per_cm))
