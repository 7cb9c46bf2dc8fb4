"""The one pixel convention (OpenCV's), the pinhole projection of a MuJoCo camera and its lens.

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


# The lens model, OpenCV's radial-tangential [k1, k2, p1, p2] on normalized image coordinates
# (x right, y down, in focal lengths): one copy, shared by the renderer's lens (`vision.camera`)
# and the scenario's check that a lens can be rendered at all (`chain.scene.check_camera`).
Distortion = tuple[float, float, float, float]
# The fold search: rays from the image centre and samples along each, out to this many times
# the image corner's radius (a lens that compresses its corners more is refused as unreachable).
FOLD_RAYS = 240
FOLD_STEPS = 800
FOLD_REACH = 4.0


def distort_normalized(x: np.ndarray, y: np.ndarray, distortion: Distortion
                       ) -> tuple[np.ndarray, np.ndarray]:
    """Ideal (pinhole) normalized coordinates -> where the lens images them (the forward map)."""
    k1, k2, p1, p2 = distortion
    r2 = x * x + y * y
    radial = 1 + k1 * r2 + k2 * r2 * r2
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    return xd, yd


def distortion_jacobian_det(x: np.ndarray, y: np.ndarray, distortion: Distortion) -> np.ndarray:
    """det d(xd, yd)/d(x, y) of `distort_normalized`: where it is not positive the lens folds
    the image over itself (two scene points on one pixel) and has no inverse."""
    k1, k2, p1, p2 = distortion
    r2 = x * x + y * y
    radial = 1 + k1 * r2 + k2 * r2 * r2
    slope = 2 * k1 + 4 * k2 * r2                     # d(radial)/d(r2) times 2
    dxx = radial + x * x * slope + 2 * p1 * y + 6 * p2 * x
    dyy = radial + y * y * slope + 6 * p1 * y + 2 * p2 * x
    cross = x * y * slope + 2 * p1 * x + 2 * p2 * y      # d(xd)/dy = d(yd)/dx for this model
    return dxx * dyy - cross * cross


def lens_fold(half_width: float, half_height: float, distortion: Distortion) -> float | None:
    """How far from the centre (normalized, distorted) the lens first folds inside an image of
    these normalized half-extents, or None when it is one-to-one over the whole image.

    Walks rays out from the centre in ideal coordinates until their image leaves the frame,
    requiring a positive Jacobian all the way: the region a renderer must invert (for each
    distorted pixel, its pinhole source), and only that one (a lens may fold beyond its field).
    A ray that never leaves the frame within `FOLD_REACH` corner radii counts as folded where it
    stops, since the frame's edge is then out of the lens's reach."""
    corner = float(np.hypot(half_width, half_height))
    angle = np.linspace(0.0, 2 * np.pi, FOLD_RAYS, endpoint=False)[:, None]
    r = np.linspace(0.0, FOLD_REACH * corner, FOLD_STEPS + 1)[None, 1:]
    x, y = r * np.cos(angle), r * np.sin(angle)
    xd, yd = distort_normalized(x, y, distortion)
    inside = np.cumprod((np.abs(xd) <= half_width) & (np.abs(yd) <= half_height), axis=1) > 0
    bad = inside & (distortion_jacobian_det(x, y, distortion) <= 0)
    bad[:, -1] |= inside[:, -1]
    rays = np.flatnonzero(bad.any(axis=1))
    if not len(rays):
        return None
    first = bad[rays].argmax(axis=1)                 # each folding ray's first bad sample
    return float(np.hypot(xd[rays, first], yd[rays, first]).min())
