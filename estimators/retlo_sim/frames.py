"""The module frame of the §2.5 networks and the features they see (pure numpy).

Frame: origin at the module's reference robot (the real or fictitious Tail) at step t, x axis
along the line from it to its Follower at t, y to the left; headings are taken relative to that
axis. Why: the dissertation expresses positions relative to the Tail (the Tail only knows others
relative to itself, §2.5.1.1) but keeps compass axes and absolute headings for simplicity. The
motion rules of §2.3 do not depend on compass heading, so a rotated frame lets 20 treatments
cover every heading a test run meets. The axis comes from the Tail→Follower line, not from the
Tail's heading, because that line is what the Tail measures, and in the modular chain
(§2.5.1.2) both ends are already estimated for every fictitious Tail, whereas a fictitious
Tail's heading would add one more recursive estimate. A consequence: the Follower's y at t is
always 0; it stays as an input only to keep the seed's six-input layout (its weights see a
constant 0 after standardization and learn nothing from it).

Feature order, shared by training and estimation:
  base (B, 5) = x_F@t, y_F@t, θ_F@t, x_F@t+1, y_F@t+1   (the seed's s_F@t, p_F@t+1)
  targets (B, 3) = x_H@t, y_H@t, θ_F@t+1
Positions in metres, angles in radians wrapped to (-π, π]. The frame maths (`frame_of`,
`to_frame`, `from_frame`) is `estimators.retlo.frames`', shared by both chapters.
"""

from __future__ import annotations

import numpy as np

from macrostate_mj.core.angles import wrap_angle
from macrostate_mj.core.frames import frame_of, from_frame, to_frame


def module_base(ref_xy: np.ndarray, fol_pose: np.ndarray, fol_xy_next: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Inputs of ANN_x (B, 5) from the reference position at t, the Follower's pose at t and its
    position at t+1 (all world frame); also the frame (origin, α) to decode the outputs."""
    origin, alpha = frame_of(ref_xy, fol_pose[..., :2])
    here = to_frame(fol_pose[..., :2], origin, alpha)
    there = to_frame(fol_xy_next, origin, alpha)
    theta = wrap_angle(fol_pose[..., 2] - alpha)[..., None]
    return np.concatenate([here, theta, there], axis=-1), origin, alpha


def module_targets(head_xy: np.ndarray, fol_theta_next: np.ndarray, origin: np.ndarray,
                   alpha: np.ndarray) -> np.ndarray:
    """Targets (B, 3): the Head's position at t in the frame, the Follower's heading at t+1."""
    return np.concatenate([to_frame(head_xy, origin, alpha),
                           wrap_angle(fol_theta_next - alpha)[..., None]], axis=-1)


def decode(out: np.ndarray, origin: np.ndarray, alpha: np.ndarray
           ) -> tuple[np.ndarray, np.ndarray]:
    """Network outputs (B, 3) → the Head's world position (B, 2) and the Follower's world
    heading at t+1 (B,)."""
    return from_frame(out[..., :2], origin, alpha), wrap_angle(out[..., 2] + alpha)


def training_pairs(poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(base, targets) of every step pair of 3-robot runs: poses (..., S, 3, 3) in the pose
    log's order (H, F1, T) → base (M, 5), targets (M, 3) with M = runs · (S - 1)."""
    p = np.asarray(poses, np.float64).reshape(-1, *poses.shape[-3:])
    head, fol, tail = p[:, :-1, 0], p[:, :-1, 1], p[:, :-1, 2]
    nxt = p[:, 1:, 1]
    base, origin, alpha = module_base(tail[..., :2], fol, nxt[..., :2])
    targets = module_targets(head[..., :2], nxt[..., 2], origin, alpha)
    return base.reshape(-1, 5), targets.reshape(-1, 3)
