"""ROC AUC with unstable = positive class, overall and per time bin; bootstrap intervals and a
paired test between two methods scored on the same samples.

Why a stratified bootstrap: the stable test set (~266) and the unstable set are sampled
separately, so each resample redraws each class with replacement from itself (scipy's
`bootstrap` with independent samples). The paired test redraws the same samples for both
methods, so the correlation between their scores on a sample cancels in the difference."""

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


def rank_auc(neg: np.ndarray, pos: np.ndarray) -> float:
    """The same AUC from mid-ranks (Mann-Whitney U / (n_pos n_neg)): no sort per threshold,
    fast enough for thousands of resamples."""
    from scipy.stats import rankdata

    ranks = rankdata(np.r_[neg, pos])
    n_neg, n_pos = len(neg), len(pos)
    return float((ranks[n_neg:].sum() - n_pos * (n_pos + 1) / 2) / (n_neg * n_pos))


def auc_interval(neg: np.ndarray, pos: np.ndarray, n_resamples: int = 2000, seed: int = 0,
                 level: float = 0.95) -> tuple[float, float] | None:
    """Percentile bootstrap interval of the AUC, each class resampled from itself; None when a
    class has fewer than 2 samples."""
    from scipy.stats import bootstrap

    neg, pos = np.asarray(neg, np.float64).ravel(), np.asarray(pos, np.float64).ravel()
    if min(len(neg), len(pos)) < 2:
        return None
    res = bootstrap((neg, pos), rank_auc, n_resamples=n_resamples, confidence_level=level,
                    method="percentile", vectorized=False, rng=np.random.default_rng(seed))
    return float(res.confidence_interval.low), float(res.confidence_interval.high)


def paired_auc_test(neg_a: np.ndarray, pos_a: np.ndarray, neg_b: np.ndarray, pos_b: np.ndarray,
                    n_resamples: int = 2000, seed: int = 0) -> dict:
    """Method a against method b on the same samples (neg_a[i] and neg_b[i] score the same
    stable sample): AUC difference a − b and the two-sided p-value of a paired stratified
    bootstrap (the share of resampled differences on the far side of 0, doubled)."""
    neg_a, pos_a, neg_b, pos_b = (np.asarray(v, np.float64).ravel()
                                  for v in (neg_a, pos_a, neg_b, pos_b))
    if len(neg_a) != len(neg_b) or len(pos_a) != len(pos_b):
        raise ValueError("paired_auc_test needs both methods' scores of the same samples")
    diff = rank_auc(neg_a, pos_a) - rank_auc(neg_b, pos_b)
    rng = np.random.default_rng(seed)
    boot = np.empty(n_resamples)
    for r in range(n_resamples):
        i = rng.integers(0, len(neg_a), len(neg_a))
        j = rng.integers(0, len(pos_a), len(pos_a))
        boot[r] = rank_auc(neg_a[i], pos_a[j]) - rank_auc(neg_b[i], pos_b[j])
    tail = min((boot <= 0).mean(), (boot >= 0).mean())
    return {"diff": float(diff), "p": float(min(1.0, 2 * tail)), "resamples": n_resamples}


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


def interval_report(stable: np.ndarray, unstable: np.ndarray, bins: Sequence[str | None],
                    bin_names: Sequence[str], seed: int = 0) -> dict:
    """Bootstrap 95 % intervals of `auc_report`'s AUCs: {"all": [lo, hi], "bins": {...}}."""
    bins_arr = np.asarray([b if b is not None else "" for b in bins], dtype=object)
    unstable = np.asarray(unstable)
    return {"all": auc_interval(stable, unstable, seed=seed),
            "bins": {n: auc_interval(stable, unstable[bins_arr == n], seed=seed)
                     for n in bin_names}}


def paired_report(stable_a: np.ndarray, unstable_a: np.ndarray, stable_b: np.ndarray,
                  unstable_b: np.ndarray, bins: Sequence[str | None], bin_names: Sequence[str],
                  seed: int = 0) -> dict:
    """`paired_auc_test` overall and per bin (a bin with fewer than 2 samples: None)."""
    bins_arr = np.asarray([b if b is not None else "" for b in bins], dtype=object)
    ua, ub = np.asarray(unstable_a), np.asarray(unstable_b)
    out = {"all": paired_auc_test(stable_a, ua, stable_b, ub, seed=seed), "bins": {}}
    for n in bin_names:
        sel = bins_arr == n
        out["bins"][n] = (paired_auc_test(stable_a, ua[sel], stable_b, ub[sel], seed=seed)
                          if sel.sum() >= 2 else None)
    return out
