"""The one pixel convention (OpenCV's) and the pinhole projection of a MuJoCo camera.

u runs right, v down, and integer coordinates sit at pixel centres: pixel (0, 0) covers
[-0.5, 0.5]². Continuous extents such as boxes use edge coordinates, `centre + 0.5`, so a box
over the whole image is (0, 0, width, height). A MuJoCo camera looks along its -z axis with +x
right and +y up in the image; the rendered array's row 0 is the top of the image.
"""

from __future__ import annotations

import numpy as np


def focal_length(height: int, fovy_deg: float) -> float:
    """Focal length in pixels of a camera with vertical field of view `fovy_deg`."""
    return float((height / 2) / np.tan(np.radians(fovy_deg) / 2))


def project(xyz: np.ndarray, position: np.ndarray, rotation: np.ndarray, focal: float,
            width: int, height: int) -> np.ndarray:
    """(..., 3) world points -> (..., 2) pixel centres (u, v); `rotation` is camera-to-world
    with the camera's x, y, z axes as columns."""
    pc = (np.asarray(xyz, float) - position) @ rotation
    depth = -pc[..., 2]
    u = width / 2 + focal * pc[..., 0] / depth - 0.5
    v = height / 2 - focal * pc[..., 1] / depth - 0.5
    return np.stack([u, v], axis=-1)
