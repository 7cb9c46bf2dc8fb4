"""2-D Gaussian estimates in numpy: how well they are calibrated, how several combine, and
the ellipse a figure draws. No torch, so that reports and figures need not import it.

Calibration (`calibration`): the share of true positions inside the estimate's p-region,
{x : (x-μ)ᵀ Σ⁻¹ (x-μ) ≤ χ²₂(p)}, with χ²₂(p) = -2 ln(1-p) for two degrees of freedom; a
calibrated model puts a share p of the truth inside it. Its NLL is -ln N(x; μ, Σ) with
positions in cm (the reports' unit), averaged.

Mixtures (`moment_match`): a deep ensemble's members, or Monte Carlo particles, give K
Gaussians per estimate; the report keeps one Gaussian with the mixture's mean and covariance
(Σ = mean Σ_i + the members' spread of means), which is what calibration and ellipses need
and keeps one shape for every consumer.
"""

from __future__ import annotations

import numpy as np

COVERAGES = (0.5, 0.9)


def chi2_2dof(p: float) -> float:
    """The Mahalanobis² radius of a 2-D Gaussian's p-region."""
    return -2.0 * np.log1p(-p)


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


def calibration(x: np.ndarray, mean: np.ndarray, cov: np.ndarray) -> dict:
    """coverage_50, coverage_90 and mean NLL of the finite estimates among (..., 2), (..., 2, 2).
    NaN estimates (steps out of reach) and covariances not positive definite in floating point
    are left out; `n` says how many counted."""
    with np.errstate(invalid="ignore", over="ignore"):
        ok = np.isfinite(mean).all(-1) & np.isfinite(cov).all((-1, -2))
        ok &= (cov[..., 0, 0] > 0) & (cov[..., 0, 0] * cov[..., 1, 1] - cov[..., 0, 1] ** 2 > 0)
    x, mean, cov = x[ok], mean[ok], cov[ok]
    d2 = mahalanobis2(x, mean, cov)
    out = {f"coverage_{round(100 * p)}": float(np.mean(d2 <= chi2_2dof(p))) for p in COVERAGES}
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
    √χ²₂(p) · Σ^½, in the unit of mean (y up or down alike: Σ carries the axes' signs)."""
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
