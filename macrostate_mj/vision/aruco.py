"""Tag tracker: each robot's ArUco tag (`chain.tags`) in an overhead RGB frame -> (x, y, theta).

The same interface as the colour `Tracker` (`track`, `track_regions`, `camera`,
`marker_radius_px`), so the camera chain drives either. Like it, it never sees ground truth.

Per tag: OpenCV's detector finds the four corners (sub-pixel) and decodes the id; ids outside
the team are ignored. The corners are undistorted with the calibrated lens and mapped to the
marker plane (`PinholeCamera.pixel_to_world`): the centre is the mean of the four world points
(exact for a square, whatever the perspective), the heading the direction from the tag's bottom
edge to its top edge (drawn forward). Obstacles that hide a tag mark it missed, as for colours.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import mujoco
import numpy as np

from macrostate_mj.chain.scene import Obstacle
from macrostate_mj.chain.tags import ArucoMarkers, dictionary
from macrostate_mj.chain.world import World
from macrostate_mj.vision.camera import PinholeCamera
from macrostate_mj.vision.occlusion import hide_occluded, scene_occluders
from macrostate_mj.vision.tracker import Detections

MIN_PERIMETER = 0.5     # of the tag's expected perimeter (px): smaller quads are not tags
WINDOW = 1.0            # `marker_radius_px` in plate sides: the plate and a margin around it


@dataclass
class ArucoTracker:
    """Finds the tags 0..n-1 of `markers`' dictionary on the plane `marker_height`."""

    camera: PinholeCamera
    markers: ArucoMarkers
    n: int
    marker_height: float         # world z of the marker plane (m)
    marker_area: float           # plate area on that plane (m^2)
    occluders: tuple[Obstacle, ...] = ()
    outline: np.ndarray = field(default_factory=lambda: np.zeros((1, 2)))   # what must show

    @classmethod
    def for_world(cls, world: World, data: mujoco.MjData,
                  distortion: tuple[float, float, float, float] | None = None) -> ArucoTracker:
        """The tracker of a compiled tag world: as `Tracker.for_world`."""
        lens = world.scenario.camera.distortion if distortion is None else distortion
        camera = PinholeCamera.from_model(world.model, data, distortion=lens)
        return cls(camera, world.scenario.markers, len(world.names), world.marker_height,
                   world.marker_area, occluders=scene_occluders(world.scenario),
                   outline=world.marker_outline)

    def __post_init__(self) -> None:
        scale = self.camera.focal / (self.camera.position[2] - self.marker_height)
        self._side_px = float(np.sqrt(self.marker_area) * scale)
        self._params = cv2.aruco.DetectorParameters()
        # Corners from lines fitted to the black frame's contour: on tags ~20 px wide, headings
        # err half as much (max 1.2 deg, hall frames) as with corner-window refinement.
        self._params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_CONTOUR
        self._detector = cv2.aruco.ArucoDetector(dictionary(self.markers.dictionary),
                                                 self._params)
        tag = self._side_px * (self.markers.cells - 2) / self.markers.cells   # black frame
        self._min_perimeter = MIN_PERIMETER * 4 * tag

    @property
    def marker_radius_px(self) -> float:
        """How far from a tag's centre the detector must see (px): the plate and a margin."""
        return WINDOW * self._side_px

    def track(self, rgb: np.ndarray) -> Detections:
        """Detections in a whole frame."""
        return self.track_regions([(0, 0, rgb)])

    def track_regions(self, parts: list[tuple[int, int, np.ndarray]]) -> Detections:
        """Detections from parts of a frame, each (x0, y0, image): a tag found in several
        parts counts once (the first)."""
        corners: dict[int, np.ndarray] = {}
        for x0, y0, img in parts:
            for tag, quad in self._detect(img):
                if tag < self.n and tag not in corners:
                    corners[tag] = quad + (x0, y0)
        poses = np.full((self.n, 3), np.nan)
        detected = np.zeros(self.n, bool)
        if corners:
            ids = np.fromiter(corners, int)
            world = self.camera.pixel_to_world(np.stack([corners[i] for i in ids]),
                                               self.marker_height)          # (k, 4, 2)
            centre = world.mean(axis=1)
            ahead = world[:, 0] + world[:, 1] - world[:, 2] - world[:, 3]   # top edge - bottom
            poses[ids] = np.column_stack([centre, np.arctan2(ahead[:, 1], ahead[:, 0])])
            detected[ids] = True
        hide_occluded(poses, detected, self.marker_height, self.camera.position, self.occluders,
                      self.outline)
        return Detections(poses, detected)

    def _detect(self, rgb: np.ndarray) -> list[tuple[int, np.ndarray]]:
        """(id, corners (4, 2) px) of each tag in one image; the perimeter bound is relative
        to the image's size in OpenCV, so it is set for each."""
        gray = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
        self._params.minMarkerPerimeterRate = self._min_perimeter / max(gray.shape)
        self._detector.setDetectorParameters(self._params)
        quads, ids, _ = self._detector.detectMarkers(gray)
        if ids is None:
            return []
        return [(int(i), q.reshape(4, 2).astype(np.float64))
                for i, q in zip(ids.ravel(), quads, strict=True) if i >= 0]
