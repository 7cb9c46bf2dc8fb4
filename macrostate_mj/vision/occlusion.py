"""Obstacles and walls as occluders of the overhead camera's view of the markers.

A marker is seen along the straight lines from its points to the camera's optical centre (a
lens bends where a ray lands on the sensor, not which ray it is). A marker counts as hidden when
one of those lines, from its centre or from a ring at half its size around it, passes through a
solid standing on the floor (an obstacle or a wall) below its top: a partly hidden marker would
be tracked off-centre, so the tracker calls it missed rather than trust what shows, as the real
testbed knows its map. A marker beside an obstacle on the side away from the camera is in full
view, and counts as seen.
"""

from __future__ import annotations

import numpy as np

from macrostate_mj.chain.scenario import ScenarioConfig
from macrostate_mj.chain.scene import Obstacle, Walls

RING = 8            # points on the marker's ring, besides its centre


def wall_boxes(arena: tuple[float, float], walls: Walls | None) -> tuple[Obstacle, ...]:
    """The arena's four walls as boxes standing outside its floor (as `chain.scene` builds
    them), to occlude like obstacles; none without walls."""
    if walls is None:
        return ()
    ax, ay, t, h = arena[0] / 2, arena[1] / 2, walls.thickness, walls.height
    return (Obstacle("box", (ax + t / 2, 0.0), (t, 2 * ay + t, h)),
            Obstacle("box", (-ax - t / 2, 0.0), (t, 2 * ay + t, h)),
            Obstacle("box", (0.0, ay + t / 2), (2 * (ax + t), t, h)),
            Obstacle("box", (0.0, -ay - t / 2), (2 * (ax + t), t, h)))


def scene_occluders(cfg: ScenarioConfig) -> tuple[Obstacle, ...]:
    """What can hide a marker in scenario `cfg`: its obstacles and its walls."""
    return tuple(cfg.obstacles) + wall_boxes(cfg.arena, cfg.walls)


def occluded(xy: np.ndarray, marker_height: float, camera: np.ndarray,
             occluders: tuple[Obstacle, ...], marker_size: float) -> np.ndarray:
    """(n,) which markers at `xy` (n, 2) on the plane `marker_height`, each `marker_size` across
    (m), a solid of `occluders` hides from a camera at `camera` (3,) world, wholly or in part.
    NaN positions are not occluded."""
    xy = np.atleast_2d(np.asarray(xy, float))
    cam = np.asarray(camera, float)
    hidden = np.zeros(len(xy), bool)
    ok = np.flatnonzero(np.isfinite(xy).all(axis=1))
    tall = [ob for ob in occluders if ob.height > marker_height]
    if not len(ok) or not tall or cam[2] <= marker_height:
        return hidden
    angle = np.linspace(0.0, 2 * np.pi, RING, endpoint=False)
    ring = np.vstack([np.zeros((1, 2)), 0.5 * marker_size * np.column_stack(
        [np.cos(angle), np.sin(angle)])])                              # (R, 2)
    start = xy[ok, None, :] + ring[None]                               # (k, R, 2)
    step = cam[:2] - start                                             # the ray's xy per unit t
    for ob in tall:
        top = min(1.0, (ob.height - marker_height) / (cam[2] - marker_height))
        lo, hi = _crossing(ob, start, step)                            # t inside the footprint
        hidden[ok] |= (np.maximum(lo, 0.0) <= np.minimum(hi, top)).any(axis=1)
    return hidden


def _crossing(ob: Obstacle, start: np.ndarray, step: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray]:
    """The interval of t (lo, hi; empty when lo > hi) in which start + t * step lies over the
    footprint of `ob` (its walls rise from the floor, so the footprint is all a ray can meet
    below the top)."""
    centre = np.asarray(ob.pos, float)
    d = start - centre
    if ob.shape == "cylinder":
        r = ob.size[0] / 2
        a = (step**2).sum(axis=-1)
        b = 2 * (d * step).sum(axis=-1)
        c = (d**2).sum(axis=-1) - r * r
        disc = b * b - 4 * a * c
        root = np.sqrt(np.maximum(disc, 0.0))
        safe = np.where(a > 0, 2 * a, 1.0)
        lo = np.where(disc >= 0, (-b - root) / safe, np.inf)
        hi = np.where(disc >= 0, (-b + root) / safe, -np.inf)
        vertical = a == 0                                   # straight up: inside or not
        lo = np.where(vertical, np.where(c <= 0, -np.inf, np.inf), lo)
        hi = np.where(vertical, np.where(c <= 0, np.inf, -np.inf), hi)
        return lo, hi
    half = np.asarray(ob.half_extents, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        t1, t2 = (-half - d) / step, (half - d) / step
    flat = step == 0                                        # parallel to a slab: in or out
    inside = np.abs(d) <= half
    lo = np.where(flat, np.where(inside, -np.inf, np.inf), np.minimum(t1, t2))
    hi = np.where(flat, np.where(inside, np.inf, -np.inf), np.maximum(t1, t2))
    return lo.max(axis=-1), hi.min(axis=-1)


def hide_occluded(poses: np.ndarray, detected: np.ndarray, marker_height: float,
                  camera: np.ndarray, occluders: tuple[Obstacle, ...], marker_area: float
                  ) -> None:
    """In place: a detection an occluder hides (`occluded`, the marker's size its area's
    square root) becomes a miss (NaN pose, not detected), as every tracker reports it."""
    if not occluders or not detected.any():
        return
    hidden = occluded(poses[:, :2], marker_height, camera, occluders, float(np.sqrt(marker_area)))
    poses[hidden] = np.nan
    detected &= ~hidden
