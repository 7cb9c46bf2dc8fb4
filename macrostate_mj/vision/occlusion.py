"""Obstacles as occluders of the overhead camera's view of the markers.

A marker is seen along the straight lines from its points to the camera's optical centre (a
lens bends where a ray lands on the sensor, not which ray it is). A marker counts as hidden when
one of those lines, from its centre or from its outline's corners and edges (the part the
tracker reads, turned with the robot: a tag's quiet border may be hidden), passes through an
obstacle below its top: a partly hidden marker would be tracked off-centre, so the tracker calls
it missed rather than trust what shows, as the real testbed knows its map. A marker beside an
obstacle on the side away from the camera is in full view, and counts as seen.
"""

from __future__ import annotations

import numpy as np

from macrostate_mj.chain.scenario import ScenarioConfig
from macrostate_mj.chain.scene import Obstacle


def scene_occluders(cfg: ScenarioConfig) -> tuple[Obstacle, ...]:
    """What can hide a marker in scenario `cfg`: its obstacles. Not its walls: they stand
    outside the floor and the camera looks straight down over its centre (`chain.scene.Camera`),
    so the line from any marker on the floor to the camera stays over the floor."""
    return tuple(cfg.obstacles)


def outline_points(poses: np.ndarray, outline: np.ndarray) -> np.ndarray:
    """(n, R, 2) the points of each marker occlusion tests, at poses (n, 3): its centre, the
    corners of its `outline` (k, 2, body frame) and their edges' midpoints, turned with it."""
    ring = np.vstack([np.zeros((1, 2)), outline, (outline + np.roll(outline, -1, axis=0)) / 2])
    c, s = np.cos(poses[:, 2]), np.sin(poses[:, 2])
    rot = np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)      # (n, 2, 2)
    return poses[:, None, :2] + ring[None] @ np.swapaxes(rot, 1, 2)


def occluded(poses: np.ndarray, marker_height: float, camera: np.ndarray,
             occluders: tuple[Obstacle, ...], outline: np.ndarray) -> np.ndarray:
    """(n,) which markers at `poses` (n, 3) on the plane `marker_height`, each of `outline`
    (k, 2, body frame: `World.marker_outline`), a solid of `occluders` hides from a camera at
    `camera` (3,) world, wholly or in part. NaN positions are not occluded; a NaN heading
    (a position alone) tests the outline unturned."""
    poses = np.atleast_2d(np.asarray(poses, float))
    cam = np.asarray(camera, float)
    hidden = np.zeros(len(poses), bool)
    ok = np.flatnonzero(np.isfinite(poses[:, :2]).all(axis=1))
    tall = [ob for ob in occluders if ob.height > marker_height]
    if not len(ok) or not tall or cam[2] <= marker_height:
        return hidden
    at = poses[ok, :3].copy()
    at[~np.isfinite(at[:, 2]), 2] = 0.0
    start = outline_points(at, np.asarray(outline, float))             # (k, R, 2)
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
                  camera: np.ndarray, occluders: tuple[Obstacle, ...], outline: np.ndarray
                  ) -> None:
    """In place: a detection an occluder hides (`occluded`, at its tracked pose) becomes a
    miss (NaN pose, not detected), as every tracker reports it."""
    if not occluders or not detected.any():
        return
    hidden = occluded(poses, marker_height, camera, occluders, outline)
    poses[hidden] = np.nan
    detected &= ~hidden
