"""The reference-robot frame a 3-robot module works in, and the features it sees (pure numpy).

Frame: origin at the module's reference robot (the real or fictitious Tail) at the prediction
time t; x axis along the line from that robot to its Follower at t; y to the left; angles
relative to that x axis. Why this frame: the dissertation (§2.5.1.1, §2.6.1.1) expresses positions
in the Tail's frame because a Tail only knows others relative to itself; we also rotate, because
the motion rules of §2.3 do not depend on compass heading, so a rotated frame lets 280 training
instances cover every heading. The x axis comes from the observed Tail→Follower direction, not
the Tail's own heading: that direction is measured directly (the Tail's heading is noisy, and
lags when it stands still), and in the modular chain (§2.5.1.2) it is known for every module from
the positions already estimated. Positions are in cm, angles in radians; world = x right, y up.
"""

from __future__ import annotations

import numpy as np

from macrostate_mj.core.angles import wrap_angle
from macrostate_mj.core.frames import frame_of, to_frame


def extrapolate_2x(ref: np.ndarray, fol: np.ndarray) -> np.ndarray:
    """The 2X heuristic of §2.6.2.3 for both chapters: the robot beyond `fol` (seen from `ref`)
    is at ref + 2 (fol - ref)."""
    return 2 * fol - ref


def angle_features(theta: np.ndarray, cos_sin: bool) -> np.ndarray:
    """Relative angles (...,) as (..., 1) radians or (..., 2) cos/sin (§3.3's option)."""
    theta = wrap_angle(theta)
    return np.stack([np.cos(theta), np.sin(theta)], -1) if cos_sin else theta[..., None]


def module_inputs(ref: np.ndarray, fol: np.ndarray, head: np.ndarray, t: int, history: int,
                  cos_sin: bool, first_estimate: int | None = None, rotate: bool = True,
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Inputs to predict the module's Head at step t, from world tracks (B, S, 3) of its robots.

    obs (B, 4): Follower positions at t and t+1 (eq. 2.2). hist (B, history, 6 or 8): Head then
    Follower pose at t-history .. t-1 (eq. 2.3). With `first_estimate` (the first step after τ),
    each history step gains a last channel, 1 where it holds fed-back estimates: the Tail knows
    τ (§2.4), and the flag lets the model learn how far to trust its own past output. Also
    returns the frame (origin, α) for decoding.
    """
    origin, alpha = frame_of(ref[:, t, :2], fol[:, t, :2], rotate)
    obs = to_frame(fol[:, t:t + 2, :2], origin, alpha).reshape(len(ref), 4)
    win = slice(t - history, t)
    parts = []
    for track in (head, fol):
        parts.append(to_frame(track[:, win, :2], origin, alpha))
        parts.append(angle_features(track[:, win, 2] - alpha[:, None], cos_sin))
    if first_estimate is not None:
        flag = (np.arange(t - history, t) >= first_estimate).astype(np.float64)
        parts.append(np.broadcast_to(flag[None, :, None], (len(ref), history, 1)))
    return obs, np.concatenate(parts, axis=-1), origin, alpha


def module_targets(fol: np.ndarray, head: np.ndarray, t: int, origin: np.ndarray,
                   alpha: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Targets of eq. 2.4 in the frame: Head position at t; (θ_F@t, θ_H@t, θ_F@t+1) - α."""
    pos = to_frame(head[:, t, :2], origin, alpha)
    ang = wrap_angle(np.stack([fol[:, t, 2], head[:, t, 2], fol[:, t + 1, 2]], -1) - alpha[:, None])
    return pos, ang
