"""ReTLo's learned modules of §2.6.1.1 and §3.3: FC (recent observations only) and LSTM.

Each is a chain `Module` (`TorchPredictor`): one 3-robot module's inputs in the reference-robot
frame (see `frames`) map to the Head's position at t and the angles (θ_F@t, θ_H@t, θ_F@t+1),
so `chain` can apply it repeatedly along a chain of any length. With a Gaussian head
(`heads`) the position comes with a covariance.

The networks work in cm, the unit they were designed and first trained in: `net_features`
scales the frame's metres to cm in float64, before the float32 rounding of their inputs, so
they see the numbers the cm pipeline gave them and keep its checkpoints and figures.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from torch import nn

from estimators.retlo import CM_PER_M, MODEL_KINDS
from estimators.retlo.chain import Features
from estimators.retlo.frames import FrameEstimate, Window, history_features
from estimators.retlo.gaussian import GAUSSIAN_REGIONS, Regions
from estimators.retlo.heads import POINT, Head
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
        MODEL_KINDS[self.kind]      # an unknown kind: one line naming the kinds
        if self.history < 1:
            raise UserError(f"history must be at least 1 step, got {self.history}")

    @property
    def reads_history(self) -> bool:
        """Whether this kind has the LSTM over ℓ steps of history (`MODEL_KINDS`)."""
        return MODEL_KINDS[self.kind].history


class RetloNet(nn.Module):
    """FC(k) on the observation ⊕ LSTM(m) over ℓ steps of history → FC(d) → position, angle heads.

    With kind "fc" the LSTM is absent: two fully connected layers (k, d) on the observation alone,
    the §2.6.2.3 baseline. Positions enter and leave divided by `pos_scale` (the training data's
    mean neighbour spacing) so that the network works on numbers of order one. `head` says what
    the position output is (`heads`: a point, or a Gaussian's mean and Cholesky factor).
    """

    def __init__(self, cfg: ModelConfig, pos_scale: float, head: Head = POINT) -> None:
        super().__init__()
        self.cfg = cfg
        self.head = head
        self.cov_scale = 1.0   # Σ's factor fitted on validation chains (`train.recalibrate`)
        self.regions = GAUSSIAN_REGIONS   # its p-regions' radii, fitted there too
        self.register_buffer("pos_scale", torch.tensor(float(pos_scale)))
        n_ang = 2 if cfg.cos_sin else 1
        self.f_obs = nn.Sequential(nn.Linear(4, cfg.k), nn.ReLU())
        width = cfg.k
        if cfg.reads_history:
            self.f_hist = nn.LSTM(4 + 2 * n_ang + int(cfg.mark_estimates), cfg.m, batch_first=True,
                                  bidirectional=cfg.bidirectional)
            width += cfg.m * (2 if cfg.bidirectional else 1)
        self.fuse = nn.Sequential(nn.Linear(width, cfg.d), nn.ReLU())
        self.g_p = nn.Linear(cfg.d, head.out_dim)
        self.g_theta = nn.Linear(cfg.d, 3 * n_ang)

    def scale_inputs(self, obs: torch.Tensor, hist: torch.Tensor) -> tuple[torch.Tensor, ...]:
        hist = hist.clone()
        n_ang = 2 if self.cfg.cos_sin else 1
        for start in (0, 2 + n_ang):  # Head xy, then Follower xy
            hist[..., start:start + 2] = hist[..., start:start + 2] / self.pos_scale
        return obs / self.pos_scale, hist

    def forward(self, obs: torch.Tensor, hist: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Raw position output (B, head.out_dim; scaled) and raw angle outputs (B, 3) or
        (B, 3, 2) for cos/sin."""
        obs, hist = self.scale_inputs(obs, hist)
        feats = [self.f_obs(obs)]
        if self.cfg.reads_history:
            _, (h_n, _) = self.f_hist(hist)
            feats.append(h_n.transpose(0, 1).reshape(len(obs), -1))  # final state per direction
        z = self.fuse(torch.cat(feats, dim=-1))
        ang = self.g_theta(z)
        return self.g_p(z), ang.view(len(obs), 3, 2) if self.cfg.cos_sin else ang


def decode_angles(ang: torch.Tensor, cos_sin: bool) -> torch.Tensor:
    """Network angle outputs → radians (B, 3)."""
    return torch.atan2(ang[..., 1], ang[..., 0]) if cos_sin else ang


def net_features(win: Window, cfg: ModelConfig) -> tuple[np.ndarray, np.ndarray]:
    """The network's inputs (float64): `frames.history_features` with positions in cm."""
    obs, hist = history_features(win, cfg.cos_sin, cfg.mark_estimates)
    return obs * CM_PER_M, hist * position_scale(cfg)


def position_scale(cfg: ModelConfig) -> np.ndarray:
    """Per history channel: CM_PER_M on positions (Head xy, Follower xy), 1 on angles and flag."""
    ang = [1.0] * (2 if cfg.cos_sin else 1)
    return np.array(([CM_PER_M] * 2 + ang) * 2 + [1.0] * int(cfg.mark_estimates))


class TorchPredictor:
    """A trained RetloNet as a chain `Module`. It does not feed back its θ_F@t+1: the next
    step estimates θ_F@t+1 itself, as θ_F@t, from newer inputs."""

    def __init__(self, net: RetloNet) -> None:
        self.net = net.eval()
        self.cfg = net.cfg
        self.history = net.cfg.history
        self.rotate = net.cfg.rotate

    def features(self, win: Window) -> Features:
        return net_features(win, self.cfg)

    @property
    def uncertain(self) -> bool:
        """Whether its estimates carry a covariance (`FrameEstimate.head_cov`)."""
        return self.net.head.uncertain

    @property
    def regions(self) -> Regions:
        """The radii of its p-regions (`gaussian.Regions`)."""
        return self.net.regions

    @torch.no_grad()
    def estimate(self, x: Features) -> FrameEstimate:
        obs, hist = x
        raw, ang = self.net(torch.as_tensor(obs, dtype=torch.float32),
                            torch.as_tensor(hist, dtype=torch.float32))
        head = self.net.head
        pos = (head.mean(raw) * self.net.pos_scale).double().numpy() / CM_PER_M
        ang = decode_angles(ang, self.cfg.cos_sin).double().numpy()
        tril = head.scale_tril(raw)
        cov = None
        if tril is not None:     # Σ = L Lᵀ, from spacing units to metres
            tril = tril.double() * self.net.pos_scale.double() / CM_PER_M
            cov = self.net.cov_scale * (tril @ tril.transpose(-1, -2)).numpy()
        return FrameEstimate(pos, head_theta=ang[:, 1], fol_theta=ang[:, 0], head_cov=cov)
