"""Statistics over seeds, folds and datasets, one home for every layer: a figure's mean and
spread as results files give it, paired tests and intervals, and cross-validation blocks."""

from __future__ import annotations

from typing import Any

from macrostate_mj.core.errors import UserError


def mean_std(values: list[float | None]) -> dict[str, float | int | None]:
    """A figure over seeds, splits or datasets as every results file gives it: mean, std
    (population) and count of the values present; None where there are none."""
    import numpy as np

    present = [v for v in values if v is not None]
    if not present:
        return {"mean": None, "std": None, "n": 0}
    return {"mean": float(np.mean(present)), "std": float(np.std(present)), "n": len(present)}


def show(stat: dict, digits: int = 1) -> str:
    """A `mean_std` figure as a summary line prints it: "mean ± std", or "-" when empty."""
    if stat["mean"] is None:
        return "-"
    return f"{stat['mean']:.{digits}f} ± {stat['std']:.{digits}f}"


def wilcoxon_p(differences: list[float]) -> float | None:
    """Two-sided Wilcoxon signed-rank p of paired differences; None under 2 pairs or when
    every difference is 0 (the test is undefined there)."""
    from scipy.stats import wilcoxon

    if len(differences) < 2 or not any(abs(d) > 1e-12 for d in differences):
        return None
    return float(wilcoxon(differences).pvalue)


def paired_interval(differences: list[float]) -> dict[str, float | int | None]:
    """Paired differences over seeds: their mean and its 95 % t interval (None under 2
    pairs), so a difference whose interval holds 0 reads as inconclusive."""
    import numpy as np
    from scipy.stats import ttest_1samp

    d = np.asarray(differences, float)
    if len(d) < 2:
        return {"mean": float(d.mean()) if len(d) else None, "low": None, "high": None,
                "n": len(d)}
    ci = ttest_1samp(d, 0.0).confidence_interval(0.95)
    return {"mean": float(d.mean()), "low": float(ci.low), "high": float(ci.high), "n": len(d)}


def cv_blocks(n: int, folds: int, fold: int, val_share: float) -> tuple[Any, Any, Any]:
    """(train pool, validation, test) instance indices of cross-validation fold `fold`: test is
    contiguous block `fold` of `folds` (instances overlap in time, so a random split would
    leak); the last `val_share` of the remaining instances (in order) validate."""
    import numpy as np

    if not 0 <= fold < folds <= n:
        raise UserError(f"cannot cut {n} instances into {folds} folds")
    edges = np.linspace(0, n, folds + 1).round().astype(int)
    test = np.arange(edges[fold], edges[fold + 1])
    rest = np.setdiff1d(np.arange(n), test)
    n_val = max(1, int(round(val_share * len(rest))))
    return rest[:-n_val], rest[-n_val:], test
