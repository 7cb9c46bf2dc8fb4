"""The one-class methods by name (`METHODS`), each registered where its score is defined: the
stages it needs trained (in training order) and how a fitted `model.OCModel` (typed `Any`
here: that module imports this one) scores inputs with it (higher = unstable). Light to import
(torch only inside the scores), so the CLI lists the names without torch; the order of
registration is the order of every report's columns.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from macrostate_mj.core.registry import Registry
from macrostate_mj.vision.flow import BOUND

if TYPE_CHECKING:
    import torch


@dataclass(frozen=True)
class Method:
    needs: tuple[str, ...]                                     # stages, in training order
    score: Callable[[Any, np.ndarray], np.ndarray]             # (OCModel, inputs), no grad


METHODS: Registry[Method] = Registry("one-class method")


def flow_magnitude(x: np.ndarray) -> np.ndarray:
    """Flow magnitude (px), N × m × H × W, of an N × 2m × H × W input in [−1, 1] (±BOUND px)."""
    return BOUND * np.hypot(x[:, 0::2], x[:, 1::2])


def flow_weight(x: np.ndarray) -> np.ndarray:
    """Mean flow magnitude (px) per sample: the optical-flow weight of Fig 4.7 and OFW."""
    return flow_magnitude(x).reshape(len(x), -1).mean(1)


def _on_device(model: Any, x: np.ndarray) -> torch.Tensor:
    import torch

    return torch.from_numpy(np.ascontiguousarray(x)).to(model.cfg.device)


def method(name: str, needs: tuple[str, ...]) -> Callable[[Callable], Callable]:
    """Registers the decorated score as method `name`, needing the stages `needs`."""

    def add(score: Callable) -> Callable:
        METHODS.register(name)(Method(needs, score))
        return score

    return add


@method("ofw", needs=())
def _ofw(model: Any, x: np.ndarray) -> np.ndarray:
    return flow_weight(x)


@method("dcae", needs=("dcae",))
def _dcae(model: Any, inputs: np.ndarray) -> np.ndarray:
    from estimators.oneclass import train as T

    x = _on_device(model, inputs)
    return T.reconstruction_error(model.ae, x).cpu().numpy()


@method("ocsvm", needs=("dcae", "ocsvm"))
def _ocsvm(model: Any, inputs: np.ndarray) -> np.ndarray:
    from estimators.oneclass import train as T

    x = _on_device(model, inputs)
    return -model._svm_decision(T.encode(model.ae.encoder, x).cpu())


@method("dsvdd", needs=("dcae", "dsvdd"))
def _dsvdd(model: Any, inputs: np.ndarray) -> np.ndarray:
    from estimators.oneclass import train as T

    x = _on_device(model, inputs)
    return ((T.encode(model.dsvdd, x) - model.c) ** 2).sum(1).cpu().numpy()


def _classifier(name: str) -> Callable[[Any, np.ndarray], np.ndarray]:
    """The score of a method whose classifier, on DSVDD's codes, was trained against its own
    generated codes."""

    def score(model: Any, inputs: np.ndarray) -> np.ndarray:
        import torch

        from estimators.oneclass import train as T

        codes = T.encode(model.dsvdd, _on_device(model, inputs))
        return torch.cat([model.classifiers[name](v) for v in codes.split(512)]).cpu().numpy()

    return score


method("gen", needs=("dcae", "dsvdd", "gen", "cls_gen"))(_classifier("gen"))
method("ngen", needs=("dcae", "dsvdd", "iogen", "cls_ngen"))(_classifier("ngen"))
method("iogen", needs=("dcae", "dsvdd", "iogen", "cls_iogen"))(_classifier("iogen"))
