"""ReTLo module predictors: the 2X heuristic, FC (recent observations only) and LSTM (§2.6.1.1).

Every predictor maps one 3-robot module's inputs in the reference-robot frame (see `frames`) to
the Head's position at t and the angles (θ_F@t, θ_H@t, θ_F@t+1), so `chain.predict_chain` can
apply any of them repeatedly along a chain of any length.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np
import torch
from torch import nn

from estimators.retlo import MODEL_KINDS
from estimators.retlo.frames import extrapolate_2x
from macrostate_mj.core.errors import UserError


@dataclass(frozen=True)
class ModelConfig:
    """Sizes from §2.6.1.1 (k, m, d, ℓ); §3.3's variants (unidirectional, cos/sin) as flags."""

    kind: str = "lstm"
    k: int = 80  # observation encoder width
    m: int = 160  # LSTM width (per direction)
    d: int = 160  # fusion layer width
    history: int = 10  # ℓ, steps of history
    bidirectional: bool = True  # §2.6; §3.3 found a unidirectional LSTM as good and faster
    cos_sin: bool = False  # §3.3: angles as (cos, sin) instead of radians
    mark_estimates: bool = True  # flag fed-back history steps (an addition; see frames)
    rotate: bool = True  # frame axes along Tail→Follower; False: compass axes as in §2.5.1.1

    def __post_init__(self) -> None:
        if self.kind not in MODEL_KINDS:
            raise UserError(f"unknown model {self.kind!r}; choose one of {', '.join(MODEL_KINDS)}")
        if self.history < 1:
            raise UserError(f"history must be at least 1 step, got {self.history}")


class Predictor(Protocol):
    """One module step: obs (B, 4), hist (B, ℓ, F) in cm/rad → pos (B, 2) cm, angles (B, 3) rad."""

    history: int
    cos_sin: bool
    mark_estimates: bool
    rotate: bool

    def predict(self, obs: np.ndarray, hist: np.ndarray) -> tuple[np.ndarray, np.ndarray]: ...


class Heuristic2X:
    """Head ≈ Tail + 2·(F − Tail) (§2.6.2.3); headings along the chain, i.e. 0 in the frame."""

    history = 10  # uses no history, but starts predicting where the learned models do
    cos_sin = False
    mark_estimates = False
    rotate = True

    def predict(self, obs: np.ndarray, hist: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return extrapolate_2x(0.0, obs[:, :2]), np.zeros((len(obs), 3))   # F relative to T


class RetloNet(nn.Module):
    """FC(k) on the observation ⊕ LSTM(m) over ℓ steps of history → FC(d) → position, angle heads.

    With kind "fc" the LSTM is absent: two fully connected layers (k, d) on the observation alone,
    the §2.6.2.3 baseline. Positions enter and leave divided by `pos_scale` (the training data's
    mean neighbour spacing) so that the network works on numbers of order one.
    """

    def __init__(self, cfg: ModelConfig, pos_scale: float) -> None:
        super().__init__()
        self.cfg = cfg
        self.register_buffer("pos_scale", torch.tensor(float(pos_scale)))
        n_ang = 2 if cfg.cos_sin else 1
        self.f_obs = nn.Sequential(nn.Linear(4, cfg.k), nn.ReLU())
        width = cfg.k
        if cfg.kind == "lstm":
            self.f_hist = nn.LSTM(4 + 2 * n_ang + int(cfg.mark_estimates), cfg.m, batch_first=True,
                                  bidirectional=cfg.bidirectional)
            width += cfg.m * (2 if cfg.bidirectional else 1)
        self.fuse = nn.Sequential(nn.Linear(width, cfg.d), nn.ReLU())
        self.g_p = nn.Linear(cfg.d, 2)
        self.g_theta = nn.Linear(cfg.d, 3 * n_ang)

    def scale_inputs(self, obs: torch.Tensor, hist: torch.Tensor) -> tuple[torch.Tensor, ...]:
        hist = hist.clone()
        n_ang = 2 if self.cfg.cos_sin else 1
        for start in (0, 2 + n_ang):  # Head xy, then Follower xy
            hist[..., start:start + 2] = hist[..., start:start + 2] / self.pos_scale
        return obs / self.pos_scale, hist

    def forward(self, obs: torch.Tensor, hist: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Scaled position (B, 2) and raw angle outputs (B, 3) or (B, 3, 2) for cos/sin."""
        obs, hist = self.scale_inputs(obs, hist)
        feats = [self.f_obs(obs)]
        if self.cfg.kind == "lstm":
            _, (h_n, _) = self.f_hist(hist)
            feats.append(h_n.transpose(0, 1).reshape(len(obs), -1))  # final state per direction
        z = self.fuse(torch.cat(feats, dim=-1))
        ang = self.g_theta(z)
        return self.g_p(z), ang.view(len(obs), 3, 2) if self.cfg.cos_sin else ang


def decode_angles(ang: torch.Tensor, cos_sin: bool) -> torch.Tensor:
    """Network angle outputs → radians (B, 3)."""
    return torch.atan2(ang[..., 1], ang[..., 0]) if cos_sin else ang


class TorchPredictor:
    """A trained RetloNet behind the numpy `Predictor` interface, for chain inference."""

    def __init__(self, net: RetloNet) -> None:
        self.net = net.eval()
        self.history = net.cfg.history
        self.cos_sin = net.cfg.cos_sin
        self.mark_estimates = net.cfg.mark_estimates
        self.rotate = net.cfg.rotate

    @torch.no_grad()
    def predict(self, obs: np.ndarray, hist: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        pos, ang = self.net(torch.as_tensor(obs, dtype=torch.float32),
                            torch.as_tensor(hist, dtype=torch.float32))
        pos = pos * self.net.pos_scale
        return pos.double().numpy(), decode_angles(ang, self.cos_sin).double().numpy()
