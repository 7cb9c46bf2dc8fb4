"""Vision tracker: each robot's coloured triangle in an overhead RGB frame -> (x, y, theta).

Pure OpenCV + numpy, and it never sees ground truth: only the frame, the calibrated camera
model, the marker colours and the marker's size, as on the real testbed (seed §2.6.2).

Per robot: pixels whose hue is near the robot's colour (saturated, not dark) are kept near their
median (so stray specks do not pull the fit); the centroid of the pixel set is the triangle's
centroid (sub-pixel: an affine view keeps centroids), the principal axis of its second moments
is the triangle's long axis, and the apex lies on the side of the centroid whose pixels spread
less across that axis (the base's half is the wider). The centroid and a point along the axis go
through the camera's plane homography to world metres at marker height.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import mujoco
import numpy as np

from macrostate_mj.chain.markers import (
    MIN_SATURATION,
    MIN_VALUE,
    apex_behind,
    hue_distance,
    hue_tolerance,
    marker_hues,
)
from macrostate_mj.chain.scene import Obstacle
from macrostate_mj.chain.world import World
from macrostate_mj.vision.camera import PinholeCamera
from macrostate_mj.vision.occlusion import hide_occluded, scene_occluders


@dataclass(frozen=True)
class Detections:
    """Per robot: world pose (n, 3) x, y, theta (NaN where missed) and detected flag (n,)."""

    poses: np.ndarray
    detected: np.ndarray


@dataclass
class Tracker:
    """Finds n triangle markers of known colours; `min_fill` of the expected area must show."""

    camera: PinholeCamera
    colours: np.ndarray          # (n, 3) RGB in [0, 1]
    marker_height: float         # world z of the marker plane (m)
    marker_area: float           # marker area on that plane (m^2)
    min_saturation: int = MIN_SATURATION     # of 255 (`chain.markers`: the one colour rule)
    min_value: int = MIN_VALUE
    min_fill: float = 0.4
    occluders: tuple[Obstacle, ...] = ()     # obstacles that can hide a marker: it is missed
    outline: np.ndarray = field(default_factory=lambda: np.zeros((1, 2)))   # what must show

    @classmethod
    def for_world(cls, world: World, data: mujoco.MjData,
                  distortion: tuple[float, float, float, float] | None = None) -> Tracker:
        """The tracker of a compiled chain world: its overhead camera as calibrated in `data`
        with the lens `distortion` (default: the scenario's, exactly), its marker colours,
        plane and area."""
        lens = world.scenario.camera.distortion if distortion is None else distortion
        camera = PinholeCamera.from_model(world.model, data, distortion=lens)
        return cls(camera, world.colours, world.marker_height, world.marker_area,
                   occluders=scene_occluders(world.scenario), outline=world.marker_outline)

    def __post_init__(self) -> None:
        self._hues = marker_hues(self.colours)
        self._hue_tol = hue_tolerance(len(self._hues))
        scale = self.camera.focal / (self.camera.position[2] - self.marker_height)
        self._area_px = self.marker_area * scale**2
        self._radius_px = 1.2 * np.sqrt(self.marker_area * 2.5) * scale

    @property
    def marker_radius_px(self) -> float:
        """How far from its centre a marker's pixels are kept (px): a generous outline."""
        return float(self._radius_px)

    def track(self, rgb: np.ndarray) -> Detections:
        """Detections in a whole frame."""
        return self.track_regions([(0, 0, rgb)])

    def track_regions(self, parts: list[tuple[int, int, np.ndarray]]) -> Detections:
        """Detections from parts of a frame, each (x0, y0, image), possibly overlapping (a pixel
        counts once): the same as `track` on a frame whose marker pixels all lie in the parts."""
        us, vs, hue = [], [], []
        seen: list[tuple[int, int, int, int]] = []
        for x0, y0, img in parts:
            hsv = cv2.cvtColor(img, cv2.COLOR_RGB2HSV_FULL)
            mask = cv2.inRange(hsv, (0, self.min_saturation, self.min_value), (255, 255, 255))
            found = cv2.findNonZero(mask)                # 6x faster than np.nonzero here
            box = (x0, y0, x0 + img.shape[1], y0 + img.shape[0])
            if found is not None:
                found = found.reshape(-1, 2)
                u, v = found[:, 0] + x0, found[:, 1] + y0
                fresh = np.ones(len(u), bool)
                for a0, b0, a1, b1 in seen:              # already counted in an earlier part
                    fresh &= ~((u >= a0) & (u < a1) & (v >= b0) & (v < b1))
                us.append(u[fresh])
                vs.append(v[fresh])
                hue.append(hsv[found[fresh, 1], found[fresh, 0], 0].astype(np.int32))
            seen.append(box)
        if len(parts) == 1 and us:          # one part: same arrays as before, no copies
            us, vs, hue = us[0], vs[0], hue[0]
        elif us:
            order = np.lexsort((np.concatenate(us), np.concatenate(vs)))  # the frame's raster
            us, vs, hue = (np.concatenate(a)[order] for a in (us, vs, hue))
        else:
            us = vs = hue = np.empty(0, np.int32)
        n = len(self._hues)
        uv = np.full((n, 2), np.nan)
        axis = np.full((n, 2), np.nan)
        detected = np.zeros(n, bool)
        for i, h in enumerate(self._hues):
            sel = hue_distance(hue, h) <= self._hue_tol
            if sel.sum() < self.min_fill * self._area_px:
                continue
            pts = np.column_stack([us[sel], vs[sel]]).astype(np.float64)
            centre = np.median(pts, axis=0)
            pts = pts[np.sum((pts - centre) ** 2, axis=1) < self._radius_px**2]
            if len(pts) < self.min_fill * self._area_px:
                continue
            c = pts.mean(axis=0)
            d = pts - c
            _, vecs = np.linalg.eigh(d.T @ d)
            e = vecs[:, 1]                               # long axis
            if apex_behind(d @ e, d @ (-e[1], e[0])):
                e = -e
            uv[i], axis[i], detected[i] = c, e, True
        poses = np.full((n, 3), np.nan)
        if detected.any():
            ok = detected
            xy = self.camera.pixel_to_world(uv[ok], self.marker_height)
            tip = self.camera.pixel_to_world(uv[ok] + 10 * axis[ok], self.marker_height)
            heading = np.arctan2(tip[:, 1] - xy[:, 1], tip[:, 0] - xy[:, 0])
            poses[ok] = np.column_stack([xy, heading])
        hide_occluded(poses, detected, self.marker_height, self.camera.position, self.occluders,
                      self.outline)
        return Detections(poses, detected)

