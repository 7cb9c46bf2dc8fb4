"""ROC AUC with unstable = positive class, overall and per time bin."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


def roc_auc(neg: np.ndarray, pos: np.ndarray) -> float:
    """P(score of a positive > score of a negative), ties counted half: scikit-learn's ROC AUC
    with the unstable samples as the positive class; NaN when either class is empty."""
    from sklearn.metrics import roc_auc_score

    neg, pos = np.asarray(neg, np.float64).ravel(), np.asarray(pos, np.float64).ravel()
    if len(neg) == 0 or len(pos) == 0:
        return float("nan")
    labels = np.r_[np.zeros(len(neg)), np.ones(len(pos))]
    return float(roc_auc_score(labels, np.r_[neg, pos]))


def auc_report(stable: np.ndarray, unstable: np.ndarray, bins: Sequence[str | None],
               bin_names: Sequence[str]) -> dict:
    """{"auc_all", "auc_bins": {name: auc of stable test vs the unstable samples of that bin}}."""
    bins_arr = np.asarray([b if b is not None else "" for b in bins], dtype=object)
    unstable = np.asarray(unstable)
    def finite(v: float) -> float | None:  # a bin without samples has no AUC (null in JSON)
        return None if np.isnan(v) else v

    return {
        "auc_all": finite(roc_auc(stable, unstable)),
        "auc_bins": {n: finite(roc_auc(stable, unstable[bins_arr == n])) for n in bin_names},
        "n_stable": int(len(stable)),
        "n_unstable": int(len(unstable)),
        "n_unstable_bins": {n: int((bins_arr == n).sum()) for n in bin_names},
    }
