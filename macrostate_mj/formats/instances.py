"""From a 2 Hz pose log to ReTLo instances (seed §2.6.2.2, §3.4), as pure functions.

An instance is 26 consecutive log steps (13 s); one instance's end and the next one's start are
at least 7 s apart, to reduce temporal autocorrelation. ThymioLoc values are camera pixels at
the real set's scale (about 3 px/cm), origin at the arena's top-left corner, y down, and
o = atan2(-dy, dx) in integer degrees.
"""

from __future__ import annotations

import math

import numpy as np

from macrostate_mj.formats.thymioloc import from_world, to_world

INSTANCE_STEPS = 26
MIN_GAP_S = 7.0


def instance_starts(n_steps: int, log_hz: float, length: int = INSTANCE_STEPS,
                    min_gap_s: float = MIN_GAP_S, first: int = 0) -> list[int]:
    """Start indices of non-overlapping instances with at least `min_gap_s` between them."""
    gap_steps = math.ceil(min_gap_s * log_hz - 1e-9)
    period = length - 1 + gap_steps
    return list(range(first, n_steps - length + 1, period))


def cut_instances(poses: np.ndarray, starts: list[int], length: int = INSTANCE_STEPS
                  ) -> np.ndarray:
    """(T, n, 3) log -> (instances, length, n, 3)."""
    if not starts:
        return np.empty((0, length, *poses.shape[1:]))
    return np.stack([poses[s:s + length] for s in starts])


def to_thymioloc_pixels(poses: np.ndarray, arena: tuple[float, float],
                        px_per_cm: float) -> np.ndarray:
    """World (x, y m from the arena centre, theta rad) -> ThymioLoc (x px, y px down, o deg)."""
    poses = np.asarray(poses, float)
    cm = np.empty_like(poses)
    cm[..., 0] = (poses[..., 0] + arena[0] / 2) * 100      # from the left wall
    cm[..., 1] = (poses[..., 1] - arena[1] / 2) * 100      # from the top wall, y up
    cm[..., 2] = poses[..., 2]
    return from_world(cm, px_per_cm)


def from_thymioloc_pixels(px: np.ndarray, arena: tuple[float, float],
                          px_per_cm: float) -> np.ndarray:
    """Inverse of `to_thymioloc_pixels`: ThymioLoc pixels/degrees -> world m, m, rad."""
    cm = to_world(px, px_per_cm)
    out = np.empty_like(cm)
    out[..., 0] = cm[..., 0] / 100 - arena[0] / 2
    out[..., 1] = cm[..., 1] / 100 + arena[1] / 2
    out[..., 2] = cm[..., 2]
    return out


def split_indices(n: int, fractions: tuple[float, ...], rng: np.random.Generator
                  ) -> list[np.ndarray]:
    """A seeded random partition of range(n) into len(fractions) sorted parts."""
    order = rng.permutation(n)
    bounds = np.round(np.cumsum(fractions) / np.sum(fractions) * n).astype(int)
    parts = np.split(order, bounds[:-1])
    return [np.sort(p) for p in parts]
