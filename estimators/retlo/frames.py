"""The reference-robot frame a 3-robot module works in, and what each module sees in it.

Frame: origin at the module's reference robot (the real or fictitious Tail) at the prediction
step t; x axis along the line from that robot to its Follower at t; y to the left; angles
relative to that x axis. Why this frame: the dissertation (§2.5.1.1, §2.6.1.1) expresses
positions in the Tail's frame because a Tail only knows others relative to itself; we also
rotate, because the motion rules of §2.3 do not depend on compass heading, so a rotated frame
lets a few hundred training instances cover every heading. The x axis comes from the observed
Tail→Follower direction, not the Tail's own heading: that direction is measured directly (the
Tail's heading is noisy, and lags when it stands still), and in the modular chain (§2.5.1.2) it
is known for every module from the positions already estimated. A consequence for §2.5's
features: the Follower's y at t is always 0; it stays an input only to keep the seed's six-input
layout. The frame maths itself is `macrostate_mj.core.frames`'.

Feature layouts, shared by training and estimation (metres, radians wrapped to (-π, π]):
  §2.5 one-step (B, 5) = x_F@t, y_F@t, θ_F@t, x_F@t+1, y_F@t+1   (the seed's s_F@t, p_F@t+1)
  §2.6 history: obs (B, 4) = Follower positions at t and t+1 (eq. 2.2); hist (B, ℓ, 6|8 [+1]) =
       Head then Follower pose at t-ℓ .. t-1 (eq. 2.3), angles as radians or cos/sin
  targets (eq. 2.4): the Head's position at t; (θ_F@t, θ_H@t, θ_F@t+1) - α
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from macrostate_mj.core.angles import wrap_angle
from macrostate_mj.core.frames import frame_of, from_frame, to_frame


@dataclass(frozen=True)
class Window:
    """A module's three robots around step t, world frame, steps t-ℓ .. t+1 on axis 1 (index ℓ
    is t), and the frame at t. The Head's step t+1 is not known yet: no module reads it."""

    ref: np.ndarray        # (B, ℓ+2, 2) reference robot positions (its heading is never used)
    fol: np.ndarray        # (B, ℓ+2, 3) the Follower's poses, headings as this module has them
    head: np.ndarray       # (B, ℓ+2, 3) the Head's poses, likewise
    estimated: np.ndarray  # (ℓ,) bool: history steps holding fed-back estimates (not truth)
    origin: np.ndarray     # (B, 2)
    alpha: np.ndarray      # (B,)

    @property
    def history(self) -> int:
        return self.fol.shape[1] - 2


def window_of(ref: np.ndarray, fol: np.ndarray, head: np.ndarray, estimated: np.ndarray,
              rotate: bool = True) -> Window:
    """The window of these tracks (B, ℓ+2, ·), framed at its step t (index ℓ). rotate=False keeps
    compass axes, the dissertation's own choice (§2.5.1.1)."""
    t = fol.shape[1] - 2
    origin, alpha = frame_of(ref[:, t, :2], fol[:, t, :2], rotate)
    return Window(ref, fol, head, estimated, origin, alpha)


@dataclass(frozen=True)
class FrameEstimate:
    """What one module step estimates: the Head's position at t, and the headings the module
    predicts (None: not predicted), and the Head position's covariance (B, 2, 2) where the
    module says how sure it is (m²; None: a point estimate). In the module frame from
    `Module.estimate`, in the world frame after `decode`."""

    head_xy: np.ndarray                       # (B, 2) the Head at t
    head_theta: np.ndarray | None = None      # (B,) θ_H@t
    fol_theta: np.ndarray | None = None       # (B,) θ_F@t
    fol_theta_next: np.ndarray | None = None  # (B,) θ_F@t+1
    head_cov: np.ndarray | None = None        # (B, 2, 2) covariance of head_xy


def decode(est: FrameEstimate, origin: np.ndarray, alpha: np.ndarray) -> FrameEstimate:
    """A module-frame estimate back in world coordinates."""
    def angle(a: np.ndarray | None) -> np.ndarray | None:
        return None if a is None else wrap_angle(a + alpha)

    cov = None
    if est.head_cov is not None:     # rotate the covariance with the points: R Σ Rᵀ
        c, s = np.cos(alpha), np.sin(alpha)
        rot = np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)
        cov = rot @ est.head_cov @ np.swapaxes(rot, -1, -2)
    return FrameEstimate(from_frame(est.head_xy, origin, alpha), angle(est.head_theta),
                         angle(est.fol_theta), angle(est.fol_theta_next), cov)


def extrapolate_2x(ref: np.ndarray | float, fol: np.ndarray) -> np.ndarray:
    """The 2X heuristic of §2.6.2.3 for both chapters: the robot beyond `fol` (seen from `ref`)
    is at ref + 2 (fol - ref)."""
    return 2 * fol - ref


def angle_features(theta: np.ndarray, cos_sin: bool) -> np.ndarray:
    """Relative angles (...,) as (..., 1) radians or (..., 2) cos/sin (§3.3's option)."""
    theta = wrap_angle(theta)
    return np.stack([np.cos(theta), np.sin(theta)], -1) if cos_sin else theta[..., None]


def one_step_features(win: Window) -> np.ndarray:
    """§2.5's inputs (B, 5): the Follower's pose at t and its position at t+1, in the frame."""
    t = win.history
    pts = to_frame(win.fol[:, t:t + 2, :2], win.origin, win.alpha)
    theta = wrap_angle(win.fol[:, t, 2] - win.alpha)[:, None]
    return np.concatenate([pts[:, 0], theta, pts[:, 1]], axis=-1)


def history_features(win: Window, cos_sin: bool, mark_estimates: bool
                     ) -> tuple[np.ndarray, np.ndarray]:
    """§2.6's inputs: obs (B, 4), hist (B, ℓ, F). With `mark_estimates` each history step gains a
    last channel, 1 where it holds fed-back estimates: the Tail knows τ (§2.4), and the flag lets
    the model learn how far to trust its own past output."""
    t, n = win.history, len(win.fol)
    obs = to_frame(win.fol[:, t:t + 2, :2], win.origin, win.alpha).reshape(n, 4)
    parts = []
    for track in (win.head, win.fol):
        parts.append(to_frame(track[:, :t, :2], win.origin, win.alpha))
        parts.append(angle_features(track[:, :t, 2] - win.alpha[:, None], cos_sin))
    if mark_estimates:
        flag = win.estimated.astype(np.float64)
        parts.append(np.broadcast_to(flag[None, :, None], (n, t, 1)))
    return obs, np.concatenate(parts, axis=-1)


def module_targets(head: np.ndarray, fol: np.ndarray, fol_next: np.ndarray, origin: np.ndarray,
                   alpha: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Targets of eq. 2.4 from true poses (B, 3) at t (t+1 for `fol_next`), in a given frame
    (the estimate's, in training on fed-back inputs): the Head's position (B, 2) and
    (θ_F@t, θ_H@t, θ_F@t+1) - α (B, 3). §2.5 learns the position and the last angle."""
    pos = to_frame(head[:, :2], origin, alpha)
    ang = wrap_angle(np.stack([fol[:, 2], head[:, 2], fol_next[:, 2]], -1) - alpha[:, None])
    return pos, ang
