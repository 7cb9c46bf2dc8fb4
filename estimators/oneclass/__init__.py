"""One-class models on optical flows (SPEC §8, §4.6): DCAE, OC-SVM, DSVDD, GEN, N-GEN, IO-GEN.

The models load lazily (PEP 562), so that the CLI can list `METHODS` (`methods.METHODS`, each
registered where its score is) without importing torch.
"""

import importlib

from estimators.oneclass.methods import METHODS

_LAZY = {"OCModel": "model", "fit": "model", "flow_weight": "methods", "OCConfig": "train"}

__all__ = ["METHODS", *_LAZY]


def __getattr__(name: str) -> object:
    if name in _LAZY:
        return getattr(importlib.import_module(f"estimators.oneclass.{_LAZY[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
