"""A reference robot's frame in the plane (pure numpy): the one home of that convention.

Frame: origin at the reference robot, x axis along the line from it to its Follower, y to the
left; positions in whatever unit the caller uses, angles radians. Chapter 2 and 3's ReTLo
modules and the SRS novelty windows use it alike (see `estimators.retlo.frames` for why).
"""

from __future__ import annotations

import numpy as np


def frame_of(ref_xy: np.ndarray, fol_xy: np.ndarray, rotate: bool = True,
             ) -> tuple[np.ndarray, np.ndarray]:
    """Origin (..., 2) and x-axis angle α (...) of the module frame at one time step: at the
    reference robot, x along the line to its Follower.

    rotate=False keeps compass axes (α = 0), the dissertation's own choice (§2.5.1.1).
    """
    ref_xy = np.asarray(ref_xy, np.float64)
    d = np.asarray(fol_xy, np.float64) - ref_xy
    alpha = np.arctan2(d[..., 1], d[..., 0])
    return ref_xy, alpha if rotate else np.zeros_like(alpha)


def _per_point(origin: np.ndarray, alpha: np.ndarray, extra: int
               ) -> tuple[np.ndarray, np.ndarray]:
    """Frames (*batch, 2) and (*batch) shaped to broadcast over `extra` point axes."""
    alpha = np.asarray(alpha)
    origin = np.asarray(origin)
    return (np.reshape(origin, origin.shape[:-1] + (1,) * extra + (2,)),
            np.reshape(alpha, alpha.shape + (1,) * extra))


def to_frame(xy: np.ndarray, origin: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """World points xy (*batch, *points, 2) into the frames (origin (*batch, 2), α (*batch))."""
    xy = np.asarray(xy, np.float64)
    origin, alpha = _per_point(origin, alpha, xy.ndim - np.ndim(origin))
    c, s = np.cos(alpha), np.sin(alpha)
    d = xy - origin
    return np.stack([c * d[..., 0] + s * d[..., 1], -s * d[..., 0] + c * d[..., 1]], axis=-1)


def from_frame(xy: np.ndarray, origin: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """Frame points xy (..., 2) back into world coordinates (origin (..., 2), α (...))."""
    c, s = np.cos(alpha), np.sin(alpha)
    return np.stack([origin[..., 0] + c * xy[..., 0] - s * xy[..., 1],
                     origin[..., 1] + s * xy[..., 0] + c * xy[..., 1]], axis=-1)
