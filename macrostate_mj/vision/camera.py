"""The overhead camera: offscreen rendering and the pinhole model that maps pixels to the floor.

Pixels follow `macrostate_mj.core.pixels` (OpenCV's convention, integer coordinates at pixel
centres), whose `project` is the one projection of the project.

Lens distortion (a scenario camera's `distortion`, OpenCV's [k1, k2, p1, p2]): MuJoCo renders an
ideal pinhole image, and `Lens` bends it into the distorted image a real lens makes; the tracker's
`PinholeCamera` undistorts detected pixels with its calibrated coefficients before they go to the
floor. Both sides use `cv2.undistortPoints` (the render's maps are that function on the pixel
grid), so a calibration equal to the lens undoes it to the solver's tolerance.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import mujoco
import numpy as np

from macrostate_mj.core.pixels import Distortion, distort_normalized, focal_length, project

NO_DISTORTION: Distortion = (0.0, 0.0, 0.0, 0.0)
# undistortPoints' fixed-point iteration: its default 5 steps leave ~0.1 px at the corners of a
# k1 = -0.2 lens; this converges to well under 1e-6 px there.
UNDISTORT_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)


def camera_matrix(width: int, height: int, focal: float) -> np.ndarray:
    """OpenCV's K of a MuJoCo camera: square pixels, principal point at the image centre in the
    pixel-centre convention (`core.pixels.project`)."""
    return np.array([[focal, 0.0, width / 2 - 0.5], [0.0, focal, height / 2 - 0.5],
                     [0.0, 0.0, 1.0]])


def undistort_pixels(uv: np.ndarray, k: np.ndarray, distortion: Distortion) -> np.ndarray:
    """(..., 2) observed (distorted) pixels -> where the ideal pinhole camera images them."""
    uv = np.asarray(uv, np.float64)
    flat = np.ascontiguousarray(uv.reshape(-1, 1, 2))
    if flat.size == 0:
        return uv.copy()
    out = cv2.undistortPoints(flat, k, np.asarray(distortion, np.float64), P=k,
                              criteria=UNDISTORT_CRITERIA)
    return out.reshape(uv.shape)


def distort_pixels(uv: np.ndarray, k: np.ndarray, distortion: Distortion) -> np.ndarray:
    """(..., 2) ideal pinhole pixels -> where the lens images them (the forward model)."""
    uv = np.asarray(uv, np.float64)
    x = (uv[..., 0] - k[0, 2]) / k[0, 0]
    y = (uv[..., 1] - k[1, 2]) / k[1, 1]
    xd, yd = distort_normalized(x, y, distortion)
    return np.stack([xd * k[0, 0] + k[0, 2], yd * k[1, 1] + k[1, 2]], axis=-1)


class Lens:
    """Bends ideal renders into distorted frames: remap maps built once per camera (for each
    output pixel, its source in the pinhole image: `undistort_pixels` on the pixel grid), one
    `cv2.remap` per frame. An ideal lens (all zero) returns frames untouched.

    A barrel lens sees more than the pinhole image of its size: its frame's edges come from
    beyond that image. With `pad`, the maps read from an ideal render `pad` = (px, py) pixels
    larger on each side (the same focal length and centre: `OverheadRenderer` renders it), so the
    whole frame is scene; without, the frame is black there (`apply`'s border)."""

    def __init__(self, width: int, height: int, focal: float,
                 distortion: Distortion = NO_DISTORTION, pad: bool = False):
        self.distortion = tuple(float(c) for c in distortion)
        self.ideal = not any(self.distortion)
        self.k = camera_matrix(width, height, focal)
        self.maps: tuple[np.ndarray, np.ndarray] | None = None
        self.pad = (0, 0)
        if not self.ideal:
            u, v = np.meshgrid(np.arange(width, dtype=np.float64),
                               np.arange(height, dtype=np.float64))
            src = undistort_pixels(np.stack([u, v], axis=-1), self.k, self.distortion)
            if pad:
                self.pad = tuple(_reach(src[..., i], size)
                                 for i, size in enumerate((width, height)))
                src = src + self.pad
            self.maps = cv2.convertMaps(src[..., 0].astype(np.float32),
                                        src[..., 1].astype(np.float32), cv2.CV_16SC2)

    def apply(self, rgb: np.ndarray) -> np.ndarray:
        """The frame this lens makes of an ideal render, `pad` larger on each side
        (bilinear; black beyond the render)."""
        if self.maps is None:
            return rgb
        return cv2.remap(rgb, *self.maps, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)


def _reach(src: np.ndarray, size: int) -> int:
    """Pixels an ideal image of `size` must grow on each side to hold every source coordinate
    in `src` (one more for the bilinear neighbour), at most `size` (a lens that reaches farther
    folds, and `chain.scene.check_camera` refuses it)."""
    beyond = max(0.0, -float(src.min()), float(src.max()) - (size - 1))
    return min(size, int(np.ceil(beyond)) + 1) if beyond > 0 else 0


@dataclass(frozen=True)
class PinholeCamera:
    """Intrinsics and pose of a MuJoCo camera, enough to project world points to pixels."""

    width: int
    height: int
    focal: float            # pixels
    position: np.ndarray    # (3,) world
    rotation: np.ndarray    # (3, 3) camera-to-world, columns = camera x, y, z axes
    distortion: Distortion = NO_DISTORTION   # the lens as calibrated: OpenCV's k1, k2, p1, p2

    @classmethod
    def from_model(cls, model: mujoco.MjModel, data: mujoco.MjData, name: str = "overhead",
                   width: int | None = None, height: int | None = None,
                   distortion: Distortion = NO_DISTORTION) -> PinholeCamera:
        cam = model.camera(name)
        w = int(width or model.cam_resolution[cam.id][0])
        h = int(height or model.cam_resolution[cam.id][1])
        return cls(w, h, focal_length(h, float(cam.fovy[0])), data.cam_xpos[cam.id].copy(),
                   data.cam_xmat[cam.id].reshape(3, 3).copy(),
                   tuple(float(c) for c in distortion))

    @property
    def matrix(self) -> np.ndarray:
        """OpenCV's camera matrix K."""
        return camera_matrix(self.width, self.height, self.focal)

    @property
    def px_per_m(self) -> float:
        """Scale on the floor plane (z = 0) for a camera looking straight down."""
        return self.focal / float(self.position[2])

    def world_to_pixel(self, xyz: np.ndarray) -> np.ndarray:
        """(..., 3) world points -> (..., 2) pixel (u, v), through the calibrated lens."""
        uv = project(xyz, self.position, self.rotation, self.focal, self.width, self.height)
        return uv if not any(self.distortion) else distort_pixels(uv, self.matrix,
                                                                   self.distortion)

    def pixel_to_world(self, uv: np.ndarray, z: float = 0.0) -> np.ndarray:
        """(..., 2) pixels -> (..., 2) world x, y on the horizontal plane at height z: the
        pixels undistorted with the calibrated lens, then the inverse of the homography between
        that plane and the image."""
        uv = np.asarray(uv, float)
        if any(self.distortion):
            uv = undistort_pixels(uv, self.matrix, self.distortion)
        ray_c = np.stack([(uv[..., 0] + 0.5 - self.width / 2) / self.focal,
                          -(uv[..., 1] + 0.5 - self.height / 2) / self.focal,
                          -np.ones(uv.shape[:-1])], axis=-1)
        ray_w = ray_c @ self.rotation.T
        s = (z - self.position[2]) / ray_w[..., 2]
        return (self.position + s[..., None] * ray_w)[..., :2]

    def homography(self, z: float = 0.0) -> np.ndarray:
        """3 x 3 H with [u, v, 1] ~ H [x, y, 1] for points on the plane at height z, in the
        ideal (undistorted) image."""
        world = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], float)
        pix = project(np.column_stack([world, np.full(4, z)]), self.position, self.rotation,
                      self.focal, self.width, self.height)
        a = []
        for (x, y), (u, v) in zip(world, pix, strict=True):
            a.append([x, y, 1, 0, 0, 0, -u * x, -u * y, -u])
            a.append([0, 0, 0, x, y, 1, -v * x, -v * y, -v])
        h = np.linalg.svd(np.array(a))[2][-1].reshape(3, 3)
        return h / h[2, 2]


class OverheadRenderer:
    """Offscreen renders of the overhead camera; close() (or `with`) frees the GL context."""

    def __init__(self, model: mujoco.MjModel, name: str = "overhead",
                 width: int | None = None, height: int | None = None,
                 distortion: Distortion = NO_DISTORTION):
        cam = model.camera(name)
        self.width = int(width or model.cam_resolution[cam.id][0])
        self.height = int(height or model.cam_resolution[cam.id][1])
        self.name = name
        focal = focal_length(self.height, float(cam.fovy[0]))
        self.lens = Lens(self.width, self.height, focal, distortion, pad=True)
        px, py = self.lens.pad
        # the ideal render the lens reads: `pad` wider on each side, the same focal length
        self._model, self._cam = model, cam.id
        self._fovy = float(np.degrees(2 * np.arctan((self.height + 2 * py) / (2 * focal))))
        size = (self.width + 2 * px, self.height + 2 * py)
        model.vis.global_.offwidth = max(model.vis.global_.offwidth, size[0])
        model.vis.global_.offheight = max(model.vis.global_.offheight, size[1])
        self._renderer = mujoco.Renderer(model, height=size[1], width=size[0])

    def render(self, data: mujoco.MjData) -> np.ndarray:
        """RGB uint8 (height, width, 3) of the current state, through the lens (if any)."""
        if self.lens.pad == (0, 0):
            self._renderer.update_scene(data, camera=self.name)
        else:                      # the padded render's field of view, for this scene only
            fovy = self._model.cam_fovy[self._cam]
            self._model.cam_fovy[self._cam] = self._fovy
            try:
                self._renderer.update_scene(data, camera=self.name)
            finally:
                self._model.cam_fovy[self._cam] = fovy
        return self.lens.apply(self._renderer.render())

    def close(self) -> None:
        self._renderer.close()

    def __enter__(self) -> OverheadRenderer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
