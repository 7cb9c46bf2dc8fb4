"""2-D Gaussian estimates in numpy: how well they are calibrated, how several combine, and
the ellipse a figure draws. No torch, so that reports and figures need not import it.

Calibration (`calibration`): the share of true positions inside the estimate's p-region,
{x : (x-μ)ᵀ Σ⁻¹ (x-μ) ≤ χ²₂(p)}, with χ²₂(p) = -2 ln(1-p) for two degrees of freedom; a
calibrated model puts a share p of the truth inside it. Its NLL is -ln N(x; μ, Σ) with
positions in cm (the reports' unit), averaged.

Regions (`Regions`): a Gaussian's p-region has the Mahalanobis² radius χ²₂(p). ReTLo's errors
are heavier-tailed than a Gaussian (most chains close, a few astray), so one covariance scale
cannot place both the 50 % and the 90 % region: the likelihood's scale covers 62 % in the first
and 89 % in the second (real 3-robot folds). A trained model therefore also carries the radii
its validation chains give: the quantiles of their Mahalanobis² (split-conformal regions on
the selection set, radial recalibration in the sense of Kuleshov et al. 2018). Its p-region is
{x : d² ≤ r²(p)}, an ellipse of Σ's shape with a calibrated size; the report gives the coverage
of those regions and, beside it, of the χ² regions of the Gaussian itself.

Mixtures (`moment_match`): a deep ensemble's members, or Monte Carlo particles, give K
Gaussians per estimate; the report keeps one Gaussian with the mixture's mean and covariance
(Σ = mean Σ_i + the members' spread of means), which is what calibration and ellipses need
and keeps one shape for every consumer.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

COVERAGES = (0.5, 0.9)     # the regions reports give
LEVELS = tuple(round(0.01 * i, 2) for i in range(1, 100))   # where fitted radii are kept


def chi2_2dof(p: float) -> float:
    """The Mahalanobis² radius of a 2-D Gaussian's p-region."""
    return float(-2.0 * np.log1p(-p))


@dataclass(frozen=True)
class Regions:
    """The Mahalanobis² radius r²(p) of an estimate's p-region: χ²₂(p) (a Gaussian's own, the
    default) or, when `tables` holds the quantiles at `LEVELS` of validation chains'
    Mahalanobis², those quantiles (interpolated between levels, clamped beyond them). One table
    per position in the chain (0: the robot module 0 estimates, next to the Tail's neighbour;
    1: the next one out; ...): a module fed estimates errs unlike one fed tracked poses, so
    each position has its own radii; positions beyond the last table use the last."""

    tables: tuple[tuple[float, ...], ...] = ()

    @classmethod
    def fitted(cls, *d2: np.ndarray) -> Regions:
        """Regions whose p-region at position j holds a share p of the j-th set of
        Mahalanobis² values."""
        tables = []
        for j, values in enumerate(d2):
            values = np.asarray(values, float)
            values = values[np.isfinite(values)]
            if values.size < 2:
                raise ValueError(f"{values.size} finite Mahalanobis² values at chain position "
                                 f"{j} fit no regions; want at least 2")
            tables.append(tuple(float(q) for q in np.quantile(values, LEVELS)))
        return cls(tuple(tables))

    @property
    def calibrated(self) -> bool:
        return bool(self.tables)

    def radius2(self, p: float, position: int | np.ndarray = 0) -> float | np.ndarray:
        """r²(p) at a chain position (or an array of positions, giving an array)."""
        if not 0.0 < p < 1.0:
            raise ValueError(f"a region's probability must be in (0, 1), got {p}")
        if not self.tables:
            return chi2_2dof(p) if np.ndim(position) == 0 else np.full(np.shape(position),
                                                                         chi2_2dof(p))
        at = np.array([np.interp(p, LEVELS, t) for t in self.tables])
        r2 = at[np.clip(position, 0, len(at) - 1)]
        return float(r2) if np.ndim(r2) == 0 else r2

    def outline_cov(self, cov: np.ndarray, p: float = 0.9,
                    position: int | np.ndarray = 0) -> np.ndarray:
        """Covariances whose Gaussian p-outline (`ellipse`, what videos and recordings draw) is
        this p-region: Σ · r²(p) / χ²₂(p), `position` broadcast against cov's leading axes."""
        return cov * (np.asarray(self.radius2(p, position)) / chi2_2dof(p))[..., None, None]

    def summary(self) -> list[dict[str, float]]:
        """r²(50 %) and r²(90 %) per position: what a training record keeps."""
        return [{f"{p:.0%}": float(np.interp(p, LEVELS, t)) for p in COVERAGES}
                for t in self.tables]

    @classmethod
    def from_record(cls, tables: object) -> Regions:
        """Regions from a checkpoint's list of tables (or one flat table), checked: each
        finite, non-negative, non-decreasing, one value per level."""
        rows = list(tables or [])  # type: ignore[call-overload]
        if rows and not isinstance(rows[0], list | tuple):
            rows = [rows]
        out = cls(tuple(tuple(float(v) for v in row) for row in rows))
        for t in out.tables:
            d2 = np.asarray(t)
            if not (d2.shape == (len(LEVELS),) and np.isfinite(d2).all() and (d2 >= 0).all()
                    and (np.diff(d2) >= 0).all()):
                raise ValueError(f"region radii must be tables of {len(LEVELS)} finite, "
                                 "non-negative, non-decreasing numbers")
        return out


GAUSSIAN_REGIONS = Regions()


def mahalanobis2(x: np.ndarray, mean: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """(x-μ)ᵀ Σ⁻¹ (x-μ) for points (..., 2) and covariances (..., 2, 2)."""
    d = x - mean
    a, b, c = cov[..., 0, 0], cov[..., 0, 1], cov[..., 1, 1]
    det = a * c - b * b
    return (c * d[..., 0] ** 2 - 2 * b * d[..., 0] * d[..., 1] + a * d[..., 1] ** 2) / det


def nll(x: np.ndarray, mean: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """-ln N(x; μ, Σ) in 2-D, per point (in the unit of x)."""
    det = cov[..., 0, 0] * cov[..., 1, 1] - cov[..., 0, 1] ** 2
    return 0.5 * mahalanobis2(x, mean, cov) + 0.5 * np.log(det) + np.log(2 * np.pi)


def calibration(x: np.ndarray, mean: np.ndarray, cov: np.ndarray,
                regions: Regions = GAUSSIAN_REGIONS, position: int | np.ndarray = 0) -> dict:
    """coverage_50, coverage_90 (of `regions`, each estimate at its chain `position`, an int or
    an array like x's leading axes) and mean NLL (of the Gaussian) of the finite estimates
    among (..., 2), (..., 2, 2); with calibrated regions, also gaussian_coverage_50 and _90, the
    χ² regions' share. NaN estimates (steps out of reach) and covariances not positive definite
    in floating point are left out; `n` says how many counted."""
    with np.errstate(invalid="ignore", over="ignore"):
        ok = np.isfinite(mean).all(-1) & np.isfinite(cov).all((-1, -2))
        ok &= (cov[..., 0, 0] > 0) & (cov[..., 0, 0] * cov[..., 1, 1] - cov[..., 0, 1] ** 2 > 0)
    x, mean, cov = x[ok], mean[ok], cov[ok]
    position = np.broadcast_to(position, ok.shape)[ok]
    d2 = mahalanobis2(x, mean, cov)
    out = {f"coverage_{round(100 * p)}": float(np.mean(d2 <= regions.radius2(p, position)))
           for p in COVERAGES}
    if regions.calibrated:
        out |= {f"gaussian_coverage_{round(100 * p)}": float(np.mean(d2 <= chi2_2dof(p)))
                for p in COVERAGES}
    return {**out, "nll": float(np.mean(nll(x, mean, cov))), "n": int(ok.sum())}


def moment_match(means: np.ndarray, covs: np.ndarray, axis: int = 0
                 ) -> tuple[np.ndarray, np.ndarray]:
    """One Gaussian with the mean and covariance of an equal-weight mixture of K Gaussians
    stacked on `axis` of means (..., 2) and covs (..., 2, 2): μ = E μ_i, Σ = E Σ_i + Cov μ_i."""
    mu = means.mean(axis=axis)
    dev = means - np.expand_dims(mu, axis)
    spread = (dev[..., :, None] * dev[..., None, :]).mean(axis=axis)
    return mu, covs.mean(axis=axis) + spread


def circular_mean(angles: np.ndarray, axis: int = 0) -> np.ndarray:
    """Mean direction of angles (radians) along `axis`."""
    return np.arctan2(np.sin(angles).mean(axis=axis), np.cos(angles).mean(axis=axis))


def ellipse(mean: np.ndarray, cov: np.ndarray, p: float = 0.9, n: int = 48) -> np.ndarray:
    """Outline (n, 2) of the p-region of N(mean (2,), cov (2, 2)): the unit circle through
    √χ²₂(p) · Σ^½, in the unit of mean (y up or down alike: Σ carries the axes' signs). A
    model's fitted region is the outline of `Regions.outline_cov`."""
    vals, vecs = np.linalg.eigh(cov)
    radii = np.sqrt(chi2_2dof(p) * np.clip(vals, 0.0, None))
    t = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    circle = np.stack([np.cos(t), np.sin(t)], -1)
    return mean + (circle * radii) @ vecs.T


def scale_cov(cov: np.ndarray, sx: float, sy: float) -> np.ndarray:
    """Covariances under the axis scaling (x, y) → (sx x, sy y): metres to pixels, y flipped
    by a negative sy."""
    s = np.array([sx, sy])
    return cov * s[:, None] * s[None, :]
