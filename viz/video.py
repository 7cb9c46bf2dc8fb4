"""Diagnostic MP4s of the overhead camera, with optional overlays (ids, waypoint, trails)."""

from __future__ import annotations

from collections import deque
from pathlib import Path

import cv2
import numpy as np

from macrostate_mj.chain.sim import ChainSim
from macrostate_mj.core.io import Mp4Writer
from macrostate_mj.vision.camera import OverheadRenderer, PinholeCamera

OVERLAYS = ("ids", "waypoint", "trails")


class Trails:
    """The last `length` positions of each robot, for drawing where the chain has been."""

    def __init__(self, n: int, length: int):
        self.points = [deque(maxlen=length) for _ in range(n)]

    def add(self, xy: np.ndarray) -> None:
        for trail, p in zip(self.points, xy, strict=True):
            trail.append(np.asarray(p, float).copy())


class Recorder:
    """The `Hook` lifecycle of a recorder: `capture` on each tick, then `finish` (keep the file)
    or `abort` (remove it). Subclasses set `period` and `phase`."""

    period: float
    phase: float = 0.0

    def initialize_episode(self, sim: ChainSim) -> None:
        pass

    def on_tick(self, sim: ChainSim) -> None:
        self.capture(sim)

    def finalize_episode(self, sim: ChainSim, keep: bool) -> None:
        self.finish() if keep else self.abort()

    def capture(self, sim: ChainSim) -> None:
        raise NotImplementedError

    def finish(self) -> None:
        raise NotImplementedError

    def abort(self) -> None:
        raise NotImplementedError


class VideoRecorder(Recorder):
    """A periodic hook: render the overhead camera, draw overlays, append to an MP4 that is
    renamed into place only by `finish()` (an interrupted run leaves no broken video)."""

    def __init__(self, path: str | Path, sim: ChainSim, fps: float = 10.0,
                 overlays: tuple[str, ...] = OVERLAYS, trail_seconds: float = 8.0):
        self.path = Path(path)
        self.sim = sim
        self.fps = fps
        self.overlays = overlays
        self.renderer = OverheadRenderer(sim.model)
        self.camera = PinholeCamera.from_model(sim.model, sim.data)
        self.trails = Trails(sim.n, max(2, int(trail_seconds * fps)))
        self._writer = Mp4Writer(self.path, fps, (self.renderer.width, self.renderer.height))
        self.period, self.phase = 1 / fps, 0.0                      # a `Hook`

    def capture(self, sim: ChainSim) -> None:
        rgb = self.renderer.render(sim.data)
        poses = sim.poses
        self.trails.add(poses[:, :2])
        bgr = np.ascontiguousarray(rgb[:, :, ::-1])
        draw_overlays(bgr, self.camera, sim, poses, self.trails, self.overlays)
        self._writer.write_bgr(bgr)

    @property
    def frames(self) -> int:
        return self._writer.frames

    def finish(self) -> None:
        """Close the file and move it into place."""
        self.renderer.close()
        self._writer.commit()

    def abort(self) -> None:
        self.renderer.close()
        self._writer.discard()


def draw_overlays(bgr: np.ndarray, camera: PinholeCamera, sim: ChainSim, poses: np.ndarray,
                  trails: Trails, overlays: tuple[str, ...]) -> None:
    z = sim.world.marker_height

    def px(xy: np.ndarray) -> np.ndarray:
        xy = np.atleast_2d(xy)
        return camera.world_to_pixel(np.column_stack([xy, np.full(len(xy), z)]))

    colours = (sim.world.colours[:, ::-1] * 255).astype(int).tolist()
    if "trails" in overlays:
        for trail, colour in zip(trails.points, colours, strict=True):
            if len(trail) > 1:
                pts = np.round(px(np.array(trail))).astype(np.int32)
                cv2.polylines(bgr, [pts], False, colour, 1, cv2.LINE_AA)
    if "waypoint" in overlays and sim.planner.target is not None:
        u, v = np.round(px(sim.planner.target)[0]).astype(int)
        cv2.circle(bgr, (int(u), int(v)), 6, (0, 0, 220), -1, cv2.LINE_AA)
    if "ids" in overlays:
        for name, (u, v) in zip(sim.world.names, px(poses[:, :2]), strict=True):
            cv2.putText(bgr, name, (int(u) + 14, int(v) - 12), cv2.FONT_HERSHEY_SIMPLEX, 0.45,
                        (20, 20, 20), 1, cv2.LINE_AA)
