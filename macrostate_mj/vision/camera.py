"""The overhead camera: offscreen rendering and the pinhole model that maps pixels to the floor.

Pixels follow `macrostate_mj.core.pixels` (OpenCV's convention, integer coordinates at pixel
centres), whose `project` is the one projection of the project.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from macrostate_mj.core.pixels import focal_length, project


@dataclass(frozen=True)
class PinholeCamera:
    """Intrinsics and pose of a MuJoCo camera, enough to project world points to pixels."""

    width: int
    height: int
    focal: float            # pixels
    position: np.ndarray    # (3,) world
    rotation: np.ndarray    # (3, 3) camera-to-world, columns = camera x, y, z axes

    @classmethod
    def from_model(cls, model: mujoco.MjModel, data: mujoco.MjData, name: str = "overhead",
                   width: int | None = None, height: int | None = None) -> PinholeCamera:
        cam = model.camera(name)
        w = int(width or model.cam_resolution[cam.id][0])
        h = int(height or model.cam_resolution[cam.id][1])
        return cls(w, h, focal_length(h, float(cam.fovy[0])), data.cam_xpos[cam.id].copy(),
                   data.cam_xmat[cam.id].reshape(3, 3).copy())

    @property
    def px_per_m(self) -> float:
        """Scale on the floor plane (z = 0) for a camera looking straight down."""
        return self.focal / float(self.position[2])

    def world_to_pixel(self, xyz: np.ndarray) -> np.ndarray:
        """(..., 3) world points -> (..., 2) pixel (u, v)."""
        return project(xyz, self.position, self.rotation, self.focal, self.width, self.height)

    def pixel_to_world(self, uv: np.ndarray, z: float = 0.0) -> np.ndarray:
        """(..., 2) pixels -> (..., 2) world x, y on the horizontal plane at height z: the
        inverse of the homography between that plane and the image."""
        uv = np.asarray(uv, float)
        ray_c = np.stack([(uv[..., 0] + 0.5 - self.width / 2) / self.focal,
                          -(uv[..., 1] + 0.5 - self.height / 2) / self.focal,
                          -np.ones(uv.shape[:-1])], axis=-1)
        ray_w = ray_c @ self.rotation.T
        s = (z - self.position[2]) / ray_w[..., 2]
        return (self.position + s[..., None] * ray_w)[..., :2]

    def homography(self, z: float = 0.0) -> np.ndarray:
        """3 x 3 H with [u, v, 1] ~ H [x, y, 1] for points on the plane at height z."""
        world = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], float)
        pix = self.world_to_pixel(np.column_stack([world, np.full(4, z)]))
        a = []
        for (x, y), (u, v) in zip(world, pix, strict=True):
            a.append([x, y, 1, 0, 0, 0, -u * x, -u * y, -u])
            a.append([0, 0, 0, x, y, 1, -v * x, -v * y, -v])
        h = np.linalg.svd(np.array(a))[2][-1].reshape(3, 3)
        return h / h[2, 2]


class OverheadRenderer:
    """Offscreen renders of the overhead camera; close() (or `with`) frees the GL context."""

    def __init__(self, model: mujoco.MjModel, name: str = "overhead",
                 width: int | None = None, height: int | None = None):
        cam = model.camera(name)
        self.width = int(width or model.cam_resolution[cam.id][0])
        self.height = int(height or model.cam_resolution[cam.id][1])
        self.name = name
        self._renderer = mujoco.Renderer(model, height=self.height, width=self.width)

    def render(self, data: mujoco.MjData) -> np.ndarray:
        """RGB uint8 (height, width, 3) of the current state."""
        self._renderer.update_scene(data, camera=self.name)
        return self._renderer.render()

    def close(self) -> None:
        self._renderer.close()

    def __enter__(self) -> OverheadRenderer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
