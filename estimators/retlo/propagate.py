"""Uncertainty carried along the modular chain (§2.5.1.2): module k's Head is module k+1's
Follower, so an uncertain estimate of it is an uncertain input there.

Choice: Monte Carlo, not moment propagation. The next module is a nonlinear network (an LSTM
over ℓ steps), its frame is built from the very Follower position that is uncertain, and its
input holds that Follower's whole recent track, whose errors across steps are correlated by
the chain's feedback: propagating moments would need a linearisation through all of that and
cross-step covariances no module predicts. Sampling needs only the module itself: P particles
(the batch tiled P times) each draw, per robot, one standard-normal z (from a seeded Generator
passed down) and read that robot, wherever another module takes it as an input, at μ_t + L_t z.
One draw for all steps because a chain estimate errs as a slow drift (`train.as_chained`
trains modules on exactly that kind of Follower error); a fresh draw each step would make the
Follower jitter, which a module reads as motion. Each module's own recursion (its fed-back
Head history) stays on its means, as in training. The report's Gaussian per robot and step
is the particles' mixture moment-matched (`gaussian.moment_match`): E Σ + Cov μ.

On 3-robot chains nothing reads an estimate, so one run (no particles) is exact.
"""

from __future__ import annotations

import numpy as np

from estimators.retlo.chain import (
    Module,
    Tracks,
    chain_estimates,
    check_chain,
    first_estimate,
    nan_covariances,
    run_chain,
    tracks_from_world,
)
from estimators.retlo.gaussian import circular_mean, moment_match
from macrostate_mj.core.errors import UserError


class NoUncertaintyError(UserError):
    """A calibration or ellipse asked of a model that gives point estimates only."""


def require_uncertain(module: Module, what: str = "calibration") -> None:
    """Refuse, in one line, a module whose estimates carry no covariance."""
    if not getattr(module, "uncertain", False):
        raise NoUncertaintyError(f"{what} needs a model with uncertainty; train one with "
                                 "`train retlo --uncertainty gaussian` (or drop the request)")


def predict_chain_gaussian(module: Module, world: np.ndarray, particles: int,
                           rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """`chain.predict_chain` with a covariance per estimate: (est (B, S, N, 3), cov (B, S, N,
    2, 2)), file order, NaN where nothing is estimated (see the module docstring)."""
    require_uncertain(module)
    check_chain(world.shape, module.history)
    if particles < 1:
        raise UserError(f"particles must be at least 1, got {particles}")
    n_runs, n_steps, n_robots, _ = world.shape
    draws = 1 if n_robots == 3 else particles
    first = first_estimate(module.history)
    tracks = tracks_from_world(np.tile(world[:, :, ::-1], (draws, 1, 1, 1)), first)
    tracks.cov = nan_covariances(tracks.head_theta.shape)
    if draws > 1:
        tracks.noise = rng.standard_normal((draws * n_runs, n_robots, 2))
    run_chain(module, tracks)

    def split(a: np.ndarray) -> np.ndarray:
        return a.reshape(draws, n_runs, *a.shape[1:])

    mean, cov = moment_match(split(tracks.pos), split(tracks.cov))
    merged = Tracks(mean, circular_mean(split(tracks.head_theta)),
                    circular_mean(split(tracks.fol_theta)), tracks.known)
    cov_out = np.full((n_runs, n_steps, n_robots, 2, 2), np.nan)
    cov_out[:, first:, 2:] = cov[:, first:, 2:]
    return chain_estimates(merged, first), cov_out[:, :, ::-1]
