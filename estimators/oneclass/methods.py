"""The one-class methods by name (`METHODS`), each registered where its score is defined: the
stages it needs trained (in training order) and how a fitted `OCModel` scores with it (higher =
unstable). Light to import (torch only inside the scores), so the CLI lists the names without
torch; the order of registration is the order of every report's columns.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from macrostate_mj.core.registry import Registry

if TYPE_CHECKING:
    import torch

    from estimators.oneclass.model import OCModel


@dataclass(frozen=True)
class Method:
    needs: tuple[str, ...]                                     # stages, in training order
    score: Callable[[OCModel, torch.Tensor], np.ndarray]       # on inputs already on the device


METHODS: Registry[Method] = Registry("one-class method")


def method(name: str, needs: tuple[str, ...]) -> Callable[[Callable], Callable]:
    """Registers the decorated score as method `name`, needing the stages `needs`."""

    def add(score: Callable) -> Callable:
        METHODS.register(name)(Method(needs, score))
        return score

    return add


@method("ofw", needs=())
def _ofw(model: OCModel, x: torch.Tensor) -> np.ndarray:
    from estimators.oneclass.model import flow_weight

    return flow_weight(x.cpu().numpy())


@method("dcae", needs=("dcae",))
def _dcae(model: OCModel, x: torch.Tensor) -> np.ndarray:
    from estimators.oneclass import train as T

    return T.reconstruction_error(model.ae, x).cpu().numpy()


@method("ocsvm", needs=("dcae", "ocsvm"))
def _ocsvm(model: OCModel, x: torch.Tensor) -> np.ndarray:
    from estimators.oneclass import train as T

    return -model._svm_decision(T.encode(model.ae.encoder, x).cpu())


@method("dsvdd", needs=("dcae", "dsvdd"))
def _dsvdd(model: OCModel, x: torch.Tensor) -> np.ndarray:
    from estimators.oneclass import train as T

    return ((T.encode(model.dsvdd, x) - model.c) ** 2).sum(1).cpu().numpy()


def _classifier(name: str) -> Callable[[OCModel, torch.Tensor], np.ndarray]:
    """The score of a method whose classifier, on DSVDD's codes, was trained against its own
    generated codes."""

    def score(model: OCModel, x: torch.Tensor) -> np.ndarray:
        import torch

        from estimators.oneclass import train as T

        codes = T.encode(model.dsvdd, x)
        return torch.cat([model.classifiers[name](v) for v in codes.split(512)]).cpu().numpy()

    return score


method("gen", needs=("dcae", "dsvdd", "gen", "cls_gen"))(_classifier("gen"))
method("ngen", needs=("dcae", "dsvdd", "iogen", "cls_ngen"))(_classifier("ngen"))
method("iogen", needs=("dcae", "dsvdd", "iogen", "cls_iogen"))(_classifier("iogen"))
