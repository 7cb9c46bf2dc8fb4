"""Obstacles as occluders of the overhead camera's view of the markers.

A marker is seen along the straight line from it to the camera; an obstacle taller than the
marker plane that this line passes through (within the marker's own size: a partly hidden
marker would be tracked off-centre) hides it. The tracker knows the lab's obstacles as the real
testbed knows its map, so it calls such a detection missed rather than trust what shows.
"""

from __future__ import annotations

import numpy as np

from macrostate_mj.chain.scene import Obstacle

SAMPLES = 33        # points along each line of sight's shadow on the floor plan


def occluded(xy: np.ndarray, marker_height: float, camera: np.ndarray,
             obstacles: tuple[Obstacle, ...], marker_radius: float) -> np.ndarray:
    """(n,) which markers at `xy` (n, 2) on the plane `marker_height` an obstacle hides from a
    camera at `camera` (3,) world: the line of sight, at heights up to the obstacle's top,
    passes over its footprint within `marker_radius`. NaN positions are not occluded."""
    xy = np.atleast_2d(np.asarray(xy, float))
    cam = np.asarray(camera, float)
    hidden = np.zeros(len(xy), bool)
    ok = np.isfinite(xy).all(axis=1)
    for ob in obstacles:
        if ob.height <= marker_height or not ok.any():
            continue
        reach = (ob.height - marker_height) / (cam[2] - marker_height)   # ray fraction at top
        s = np.linspace(0.0, min(reach, 1.0), SAMPLES)[None, :, None]
        ray = xy[ok, None, :] + s * (cam[:2] - xy[ok, None, :])           # (k, S, 2)
        dist = ob.distance(ray.reshape(-1, 2))[0].reshape(len(ray), SAMPLES)
        hidden[np.flatnonzero(ok)] |= dist.min(axis=1) < marker_radius
    return hidden


def hide_occluded(poses: np.ndarray, detected: np.ndarray, marker_height: float,
                  camera: np.ndarray, obstacles: tuple[Obstacle, ...], marker_area: float
                  ) -> None:
    """In place: a detection an obstacle hides (`occluded`, the marker's size its area's
    square root) becomes a miss (NaN pose, not detected), as every tracker reports it."""
    if not obstacles or not detected.any():
        return
    hidden = occluded(poses[:, :2], marker_height, camera, obstacles, float(np.sqrt(marker_area)))
    poses[hidden] = np.nan
    detected &= ~hidden
