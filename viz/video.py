"""MP4s of the overhead camera.

`VideoRecorder`: the diagnostic video, with overlays (ids, the Head's waypoint, trails, the clock,
the arena walls, a scale bar and, with a tracker, its detections beside the truth). By default it
shows the camera's view, through the scenario's lens distortion, as the tracker saw it; every
overlay is drawn where it lies in that image (`PinholeCamera.world_to_pixel` applies the lens).
`view="undistorted"` shows the ideal pinhole render instead.

`CameraVideo`: the raw frames the tracker was handed (lens and imaging noise, no overlays) and
their times, so `macrostate-mj track` can run the same tracker on them offline.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from fractions import Fraction
from pathlib import Path

import cv2
import numpy as np

from macrostate_mj.chain.sim import ChainSim
from macrostate_mj.core.draw import FONT, INK, PAPER, label
from macrostate_mj.core.io import Mp4Writer, write_text_atomic
from macrostate_mj.vision.camera import OverheadRenderer, PinholeCamera

OVERLAYS = ("ids", "waypoint", "trails", "clock", "walls", "scale", "detections")
VIEWS = ("camera", "undistorted")     # through the scenario's lens (what the tracker saw), or not
WALL_SAMPLES = 64                     # points per wall edge: a bending lens curves it


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
    renamed into place only by `finish()` (an interrupted run leaves no broken video). `view`:
    "camera" (through the scenario's lens) or "undistorted" (the ideal pinhole render)."""

    def __init__(self, path: str | Path, sim: ChainSim, fps: float = 10.0,
                 overlays: tuple[str, ...] = OVERLAYS, trail_seconds: float = 8.0,
                 tracker: object | None = None,
                 decorate: Callable[[np.ndarray, Callable[[np.ndarray], np.ndarray]], None]
                 | None = None, view: str = "camera"):
        if view not in VIEWS:
            raise ValueError(f"view must be one of {VIEWS}, got {view!r}")
        self.path = Path(path)
        # decorate(bgr, px): draws what the scene cannot show (a virtual object, an estimate);
        # px maps world points (k, 2) on the marker plane to pixels (k, 2)
        self.decorate = decorate
        self.sim = sim
        self.fps = fps
        self.overlays = overlays
        self.tracker = tracker          # anything with `latest` (n, 3) and `detected` (n,)
        lens = sim.cfg.camera.distortion if view == "camera" else (0.0, 0.0, 0.0, 0.0)
        self.renderer = OverheadRenderer(sim.model, distortion=lens)
        self.camera = PinholeCamera.from_model(sim.model, sim.data, distortion=lens)
        self.trails = Trails(sim.n, max(2, int(trail_seconds * fps)))
        self._writer = Mp4Writer(self.path, fps, (self.renderer.width, self.renderer.height))
        self.period, self.phase = 1 / fps, 0.0                      # a `Hook`

    def capture(self, sim: ChainSim) -> None:
        self._writer.write_bgr(self.frame(sim))

    def frame(self, sim: ChainSim) -> np.ndarray:
        """This moment's video frame (BGR), overlays drawn; adds to the trails."""
        rgb = self.renderer.render(sim.data)
        poses = sim.poses
        self.trails.add(poses[:, :2])
        bgr = np.ascontiguousarray(rgb[:, :, ::-1])
        tracked = None
        if self.tracker is not None and "detections" in self.overlays:
            tracked = np.where(self.tracker.detected[:, None], self.tracker.latest, np.nan)
        draw_overlays(bgr, self.camera, sim, poses, self.trails, self.overlays, tracked,
                      self._tracker_camera())
        if self.decorate is not None:
            z = sim.world.marker_height
            self.decorate(bgr, lambda xy: self.camera.world_to_pixel(
                np.column_stack([np.atleast_2d(xy), np.full(len(np.atleast_2d(xy)), z)])))
        return bgr

    def _tracker_camera(self) -> PinholeCamera | None:
        """The camera the tracker mapped its pixels to the floor with (its calibration): its
        poses projected back through it land on the pixels it detected them at. None in the
        undistorted view, whose pixels are not the tracker's."""
        if not any(self.camera.distortion):
            return None
        return getattr(getattr(self.tracker, "tracker", None), "camera", None)

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
                  trails: Trails, overlays: tuple[str, ...],
                  tracked: np.ndarray | None = None,
                  tracker_camera: PinholeCamera | None = None) -> None:
    """Draw the chosen overlays in place, each where `camera` images it; `tracked` (n, 3), NaN
    where missed, are the tracker's poses of this frame (crosshairs with a heading tick over the
    true robot), placed through `tracker_camera` when given (at the pixels it detected)."""
    world = sim.world
    z = world.marker_height

    def projector(cam: PinholeCamera):
        def px(xy: np.ndarray, height: float = z) -> np.ndarray:
            xy = np.atleast_2d(xy)
            return cam.world_to_pixel(np.column_stack([xy, np.full(len(xy), height)]))
        return px

    px = projector(camera)

    colours = (world.colours[:, ::-1] * 255).astype(int).tolist()
    radius = world.footprint_radius * camera.px_per_m
    if "walls" in overlays:
        outline = np.round(px(wall_outline(world.scenario.arena), 0.0))
        # walls at the frame's edge (the cameras frame the arena) are drawn just inside it
        outline = np.clip(outline, 1, [bgr.shape[1] - 2, bgr.shape[0] - 2])
        cv2.polylines(bgr, [outline.astype(np.int32)], True, INK, 2, cv2.LINE_AA)
    if "trails" in overlays:
        for trail, colour in zip(trails.points, colours, strict=True):
            if len(trail) > 1:
                pts = np.round(px(np.array(trail))).astype(np.int32)
                cv2.polylines(bgr, [pts], False, colour, 1, cv2.LINE_AA)
    if "waypoint" in overlays and sim.planner.target is not None:
        u, v = np.round(px(sim.planner.target)[0]).astype(int)
        cv2.circle(bgr, (int(u), int(v)), max(3, int(radius / 3)), (0, 0, 220), -1, cv2.LINE_AA)
    if tracked is not None:
        _draw_detections(bgr, px if tracker_camera is None else projector(tracker_camera),
                         tracked, radius)
    if "ids" in overlays:
        scale = float(np.clip(radius / 40, 0.3, 0.5))     # a label the size of the robot
        for name, (u, v) in zip(world.names, px(poses[:, :2]), strict=True):
            at = (int(u + 0.75 * radius), int(v - 0.75 * radius))
            label(bgr, name, at, scale)
    if "clock" in overlays:
        label(bgr, f"t = {sim.time:7.2f} s", (8, 20), 0.5)
    if "scale" in overlays:
        _scale_bar(bgr, camera.px_per_m, world.scenario.arena[0])


def wall_outline(arena: tuple[float, float], samples: int = WALL_SAMPLES) -> np.ndarray:
    """(4 * samples, 2) floor points around the arena's inner wall edge, corner first on each
    side: straight in the world, curved where a lens bends them."""
    hx, hy = np.array(arena, float) / 2
    corners = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy], [-hx, -hy]])
    s = np.linspace(0.0, 1.0, samples, endpoint=False)[:, None]
    return np.concatenate([a + s * (b - a) for a, b in zip(corners[:-1], corners[1:],
                                                           strict=True)])


def _draw_detections(bgr: np.ndarray, px, tracked: np.ndarray, radius: float) -> None:
    seen = np.all(np.isfinite(tracked), axis=1)
    arm = max(3, int(radius / 3))
    for x, y, th in tracked[seen]:
        u, v = np.round(px(np.array([x, y]))[0]).astype(int)
        du, dv = np.cos(th), -np.sin(th)            # image v points down
        tip = (int(u + 2 * arm * du), int(v + 2 * arm * dv))
        for colour, width in ((INK, 3), (PAPER, 1)):   # white on black: seen on any robot
            cv2.drawMarker(bgr, (int(u), int(v)), colour, cv2.MARKER_CROSS, 2 * arm, width)
            cv2.line(bgr, (int(u), int(v)), tip, colour, width, cv2.LINE_AA)
    label(bgr, "+ tracker's pose and heading; robot = truth", (8, bgr.shape[0] - 34), 0.4)


def _scale_bar(bgr: np.ndarray, px_per_m: float, arena_width: float) -> None:
    """A bar of a round length, about a fifth of the arena's width, at the bottom left."""
    length = max(m for m in (0.02, 0.05, 0.1, 0.2, 0.5, 1.0) if m <= arena_width / 4)
    u0, v0 = 10, bgr.shape[0] - 12
    u1 = u0 + int(round(length * px_per_m))
    cv2.rectangle(bgr, (u0 - 4, v0 - 16), (u1 + 4, v0 + 6), PAPER, -1)
    cv2.line(bgr, (u0, v0), (u1, v0), INK, 2)
    for u in (u0, u1):
        cv2.line(bgr, (u, v0 - 4), (u, v0 + 4), INK, 1)
    text = f"{length * 100:g} cm"
    cv2.putText(bgr, text, (u0, v0 - 6), FONT, 0.4, INK, 1, cv2.LINE_AA)


class CameraVideo(Recorder):
    """The camera's raw frames, as the tracker was handed them (lens, imaging noise; no
    overlays), each stamped in the container with the time it was taken (variable frame rate:
    a dropped frame leaves a gap, so a re-encode that keeps the stamps keeps the times), and
    the same times in a sidecar `FILE.times.csv` (frame, t), exact to the bit. Hooked after the
    camera chain, whose `film` it takes over; both files appear only on `finish()`.

    Encoding: `CameraMp4Writer`'s H.264 4:4:4, not the diagnostic video's 4:2:0, whose halved
    chroma moves the colour markers' edges (the tracker segments hue)."""

    def __init__(self, path: str | Path, chain, fps: float):
        self.path = Path(path)
        self.times_path = times_path(self.path)
        self.times: list[float] = []
        r = chain.renderer
        self._writer = CameraMp4Writer(self.path, fps, (r.width, r.height))
        chain.film(self.add)
        self.period, self.phase = 1e9, 0.0      # a `Hook` that never needs a tick

    def add(self, t: float, rgb: np.ndarray) -> None:
        self._writer.write(rgb, t)
        self.times.append(float(t))

    def capture(self, sim: ChainSim) -> None:
        pass

    @property
    def frames(self) -> int:
        return self._writer.frames

    def finish(self) -> None:
        self._writer.commit()
        write_text_atomic(self.times_path, "frame,t\n" + "".join(
            f"{i},{t!r}\n" for i, t in enumerate(self.times)))

    def abort(self) -> None:
        self._writer.discard()


def times_path(video: str | Path) -> Path:
    """The sidecar of a camera video: `FILE.times.csv` beside `FILE.mp4`."""
    video = Path(video)
    return video.with_name(f"{video.stem}.times.csv")


class CameraMp4Writer(Mp4Writer):
    """`Mp4Writer` for data, not for browsers: full-resolution chroma (yuv444p), near-lossless
    (CRF 8). lab, 20 s, no jitter: the offline track's median distance from the online one is
    0.00 mm (CRF 14: 0.16 mm at half the size; the diagnostic 4:2:0 at CRF 20: 0.31 mm).

    Each frame carries the time it was taken (`write(rgb, t)`, TIME_BASE units): a dropped
    frame's gap changes the stamps, never the pixels (`Mp4Writer`: x264 keeps to the nominal
    rate), so the same frames decode as with evenly spaced stamps."""

    PIX_FMT = "yuv444p"
    CRF = 8
    TIME_BASE = Fraction(1, 90000)      # MPEG's clock: 11 us, finer than any physics step
