"""ROC AUC with unstable = positive class, overall and per time bin (pure numpy)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


def roc_auc(neg: np.ndarray, pos: np.ndarray) -> float:
    """P(score of a positive > score of a negative), ties counted half (Mann–Whitney U)."""
    neg, pos = np.asarray(neg, np.float64).ravel(), np.asarray(pos, np.float64).ravel()
    if len(neg) == 0 or len(pos) == 0:
        return float("nan")
    scores = np.concatenate([neg, pos])
    order = scores.argsort(kind="mergesort")
    ranks = np.empty(len(scores))
    sorted_scores = scores[order]
    # average ranks over ties
    _, first, counts = np.unique(sorted_scores, return_index=True, return_counts=True)
    avg = first + (counts - 1) / 2.0 + 1.0
    ranks[order] = np.repeat(avg, counts)
    u = ranks[len(neg):].sum() - len(pos) * (len(pos) + 1) / 2.0
    return float(u / (len(neg) * len(pos)))


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
