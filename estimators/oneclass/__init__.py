"""One-class models on optical flows (SPEC §8, §4.6): DCAE, OC-SVM, DSVDD, GEN, N-GEN, IO-GEN."""

from estimators.oneclass.model import METHODS, OCModel, fit, flow_weight
from estimators.oneclass.train import OCConfig

__all__ = ["METHODS", "OCConfig", "OCModel", "fit", "flow_weight"]
