"""What a ReTLo network's position output means: a point (today's models) or a 2-D Gaussian.

A `Head` is chosen once, where the user names it (`train retlo --uncertainty`, or the name a
checkpoint records), and travels as an object: the network sizes its position layer by it, the
loss asks it for the per-sample position term, and the predictor asks it for mean and
covariance. Nothing deeper compares strings.

The Gaussian is parametrised by its Cholesky factor L = [[exp(a), 0], [b, exp(c)]] (five
outputs: mean x, y, then a, b, c). Why Cholesky rather than log-std + correlation: L is
positive definite for any real output (no tanh saturating as |ρ| → 1, no clamping), and it is
what `torch.distributions.MultivariateNormal(scale_tril=...)` takes, so the NLL needs no
factorisation of its own and stays stable when the two axes are strongly correlated (a Head
error runs mostly along the chain's direction).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch
from torch.distributions import MultivariateNormal

from macrostate_mj.core.errors import UserError


@dataclass(frozen=True)
class PointHead:
    """Today's output: the position alone, trained on its Euclidean error (§2.6.2.3)."""

    name: str = "none"
    out_dim: int = 2
    uncertain: bool = False

    def mean(self, raw: torch.Tensor) -> torch.Tensor:
        return raw

    def scale_tril(self, raw: torch.Tensor) -> torch.Tensor | None:
        return None

    def position_loss(self, raw: torch.Tensor, target: torch.Tensor,
                      mean_only: torch.Tensor | None = None) -> torch.Tensor:
        """Per-sample Euclidean error (spacing units): the same operations as before heads."""
        return torch.linalg.vector_norm(raw - target, dim=-1)


@dataclass(frozen=True)
class GaussianHead:
    """A 2-D Gaussian per sample (see the module docstring for the parametrisation), trained on
    its negative log-likelihood. `min_log_std` keeps exp(a), exp(c) above e^-7 spacing units
    (~0.03 mm): a floor that only guards the NLL against a collapsing variance. `max_log_std`
    caps exp(a), exp(c) and |b| at e^7 spacing units (tens of metres): far out of its training
    data (a chain whose estimates went astray) a network's raw outputs can overflow, and a
    shear b far above exp(c) leaves Σ's determinant to rounding.

    `beta`: each sample's NLL is weighted by σ^(2β), held fixed (β-NLL, Seitzer et al. 2022),
    σ² = √det Σ. The plain NLL (β = 0) pulls the mean by Σ⁻¹(μ - y): samples it finds hard it
    declares uncertain and then learns little from, and the mean falls behind a point model's.
    β = ½ pulls by about (μ - y)/σ, the weighting of the point model's Euclidean loss when σ
    follows the error's size. The weight moves no sample's optimum: Σ is still fitted to the
    errors, so calibration is kept.

    `faithful`: the mean is trained on the point model's Euclidean error and Σ on the NLL of
    the detached mean (Stirn et al. 2023, "faithful heteroscedastic regression"), so the
    covariance cannot pull the mean away from what a point model learns; β is then unused.
    Measured against β-NLL on the real folds: docs, reproduction/beyond."""

    name: str = "gaussian"
    out_dim: int = 5
    uncertain: bool = True
    min_log_std: float = -7.0
    max_log_std: float = 7.0
    beta: float = 0.5
    faithful: bool = False

    def mean(self, raw: torch.Tensor) -> torch.Tensor:
        return raw[..., :2]

    def scale_tril(self, raw: torch.Tensor) -> torch.Tensor:
        """L (..., 2, 2), lower triangular with a positive diagonal."""
        a = raw[..., 2].clamp(self.min_log_std, self.max_log_std).exp()
        c = raw[..., 4].clamp(self.min_log_std, self.max_log_std).exp()
        bound = math.exp(self.max_log_std)
        b = raw[..., 3].clamp(-bound, bound)
        zero = torch.zeros_like(a)
        return torch.stack([torch.stack([a, zero], -1), torch.stack([b, c], -1)], -2)

    def distribution(self, raw: torch.Tensor) -> MultivariateNormal:
        return MultivariateNormal(self.mean(raw), scale_tril=self.scale_tril(raw))

    def position_loss(self, raw: torch.Tensor, target: torch.Tensor,
                      mean_only: torch.Tensor | None = None) -> torch.Tensor:
        """Per-sample negative log-likelihood of the target (spacing units). Where `mean_only`
        is 1, the covariance is held fixed (detached) and the NLL trains the mean alone: see
        `train._with_feedback` for the samples that need it."""
        tril = self.scale_tril(raw)
        if mean_only is not None:
            tril = torch.where(mean_only.view(-1, 1, 1) > 0, tril.detach(), tril)
        if self.faithful:
            return POINT.position_loss(self.mean(raw), target) - MultivariateNormal(
                self.mean(raw).detach(), scale_tril=tril).log_prob(target)
        nll = -MultivariateNormal(self.mean(raw), scale_tril=tril).log_prob(target)
        if self.beta == 0.0:
            return nll
        sigma2 = (tril[..., 0, 0] * tril[..., 1, 1]).detach()    # √det Σ
        return sigma2 ** self.beta * nll


Head = PointHead | GaussianHead
POINT, GAUSSIAN = PointHead(), GaussianHead()
FAITHFUL = GaussianHead(name="gaussian-faithful", faithful=True)
HEADS: dict[str, Head] = {h.name: h for h in (POINT, GAUSSIAN, FAITHFUL)}


def head_named(name: str) -> Head:
    """The head a CLI flag or a checkpoint names; anything else refused in one line."""
    if name not in HEADS:
        raise UserError(f"unknown uncertainty {name!r}; choose one of {', '.join(HEADS)}")
    return HEADS[name]
