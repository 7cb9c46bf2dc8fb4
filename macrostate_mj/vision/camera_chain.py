"""The overhead camera chain as a periodic hook: render -> imaging noise -> tracker.

It keeps the latest detection of every robot (and when it was made), as the real testbed's
logger did: the 2 Hz pose log records whatever the 4 Hz tracker saw last, up to one command
period earlier (`t_trk` in the log says exactly when). A robot missed in a frame keeps its previous
tracked pose (NaN before its first detection) with `detected` False.

Frames are filmed lazily, with exactly the eager results. A frame's draws (drop, noise) are made
when it is taken, but its render, imaging and tracking wait until someone reads the tracker
(`latest`, `detected`, ...) or the next frame is taken. The next frame is then processed first:
if it sees every robot, it overwrites everything the waiting frame would have set, so that frame
is never rendered; otherwise the waiting frame is rendered from a copy of the physics state it
was taken in (`mj_copyData`: the same pixels) and applied first. With a 2 Hz log over 4 Hz
frames about half the frames are never rendered.

Where every robot was seen in the last processed frame, imaging and tracking run only in a
window around each (`regions`): the window holds the marker wherever the robot can have driven
since, and `imaging.regions` makes its pixels exactly as the whole frame's chain would. After a
miss or a dropped frame, or with `windows=False`, the whole frame is processed.

Frames are taken at the scenario's `frame_hz` (the command rate unless set), each delayed by
up to `frame_jitter` s (its own stream, drawn only when above zero): the 2 Hz log then records
frames of uneven age. With `frame_alternation` the frames are taken in step with the log, those
every other row reads that much earlier: the rows alternate between two frame ages, shared by
every robot of a row, and the logged speeds alternate from row to row (as the real ones do).
A `marker_offset` moves each robot's tracked point off its body's centre (drawn per episode,
turning with the body): real markers are not stuck on exactly.

The scenario's `marker_jitter` adds white Gaussian noise to every tracked position (the Head's
scaled by `head_jitter_scale`), drawn per frame from the imaging stream (only when it is above
zero, so a scenario without it keeps its outputs bit for bit). It stands for what our rendered
markers lack and the real ThymioLoc tracker shows (about 0.25 cm of jitter around a smooth
track, a Head speed whose lag-1 autocorrelation is negative): paper markers that flex and rock
with the body, uneven light, a detector on real edges. The windows are placed from the
positions before it.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import mujoco
import numpy as np

from macrostate_mj.chain.sim import ChainSim
from macrostate_mj.core.frames import from_frame
from macrostate_mj.vision import imaging
from macrostate_mj.vision.camera import OverheadRenderer
from macrostate_mj.vision.health import HealthMonitor
from macrostate_mj.vision.imaging import FrameDraw, NoiseConfig, SceneConditions, draw_episode
from macrostate_mj.vision.tracker import Detections
from macrostate_mj.vision.trackers import tracker_for


@dataclass
class _Frame:
    """A frame taken but not yet processed: the physics state it shows, when, the true poses
    then, and its imaging draws."""

    data: mujoco.MjData
    time: float
    truth: np.ndarray
    draw: FrameDraw
    jitter: np.ndarray | None


class CameraChain:
    """Owns a renderer; `start(rng)` once per episode, then `capture` at the command rate, then
    `close()`. As a `Hook` (given `rng`), `ChainSim.episode` makes those calls itself.

    With `lazy=False` every frame is rendered and processed when it is taken (the results are
    the same: tested). `health` (a `vision.health.HealthMonitor`, or None with `health=False`)
    compares every processed frame's detections with the truth of that moment. `film(on_frame)`
    hands every whole frame the tracker processes to `on_frame(t, rgb)`, as the imaging chain
    delivered it."""

    def __init__(self, sim: ChainSim, noise: NoiseConfig | None = None,
                 rng: np.random.Generator | None = None, phase: float = 0.0,
                 windows: bool = True, lazy: bool = True, health: bool = True):
        self.sim = sim
        self.on_frame: Callable[[float, np.ndarray], None] | None = None    # see `film`
        self.period, self.phase = 1 / sim.cfg.camera_hz, phase      # a `Hook`: frame rate
        self._phase = phase         # as given (`start` puts the frames in step with the log)
        self._episode_rng = rng
        self.noise = noise or sim.cfg.imaging       # default: the scenario's own
        self.renderer = OverheadRenderer(sim.model, distortion=sim.cfg.camera.distortion)
        self.conditions = SceneConditions(sim.model)
        n = len(sim.world.names)
        self._latest = np.full((n, 3), np.nan)
        self._placed = np.full((n, 2), np.nan)     # where the windows go: before the jitter
        self._latest_time = np.full(n, np.nan)     # when each robot was last seen (s)
        self._latest_truth = np.full((n, 3), np.nan)   # its true pose at that moment
        self._detected = np.zeros(n, bool)
        self._seen_at = np.nan           # time of the frame behind `_latest` when all were seen
        self.frames = self.dropped = self._windowed = self._rendered = 0
        self.windows, self.lazy = windows, lazy
        self._waiting: _Frame | None = None
        self._spare = mujoco.MjData(sim.model)     # the waiting frame's copy of the state
        self.health = HealthMonitor.for_world(sim.world) if health else None

    def start(self, rng: np.random.Generator) -> None:
        """Calibrate on the nominal camera (its lens as this episode's draw misjudges it), then
        apply this episode's conditions."""
        sim = self.sim
        self._waiting = None
        self.conditions.restore()
        mujoco.mj_forward(sim.model, sim.data)
        self.rng = rng
        self._offset = None
        # frames that alternate with the log's rows are taken in step with it
        self.phase = sim.log_phase if sim.cfg.frame_alternation > 0 else self._phase
        if sim.cfg.frame_alternation > 0 or sim.cfg.frame_jitter > 0:
            self.tick_time = self._timed
        if sim.cfg.frame_jitter > 0 or sim.cfg.marker_offset > 0:
            # streams of their own (children of the imaging stream's seed, which they leave as
            # it was): each frame's delay, and each robot's marker offset on its body
            self._timing, placing = rng.spawn(2)
            if sim.cfg.marker_offset > 0:
                self._offset = placing.normal(0.0, sim.cfg.marker_offset,
                                              (len(sim.world.names), 2))
        shape = (self.renderer.height, self.renderer.width, 3)
        self.episode = draw_episode(self.noise, rng, shape)
        self.tracker = tracker_for(     # the world's marker kind's tracker
            sim.world, sim.data, self.episode.calibrated(sim.cfg.camera.distortion))
        self.conditions.apply(self.episode)
        mujoco.mj_forward(sim.model, sim.data)
        # Where the camera truly is this episode: what hides a marker, by the truth (health).
        self._camera_at = sim.data.cam_xpos[self.conditions.cam].copy()
        self._latest[:] = np.nan
        self._placed[:] = np.nan
        self._latest_time[:] = np.nan
        self._latest_truth[:] = np.nan
        self._detected[:] = False
        self._seen_at = np.nan
        if self.health is not None:
            self.health.reset()

    def _timed(self, count: int) -> float:
        """When frame `count` is taken (s after the first nominal instant; `ChainSim` asks
        once per frame): its nominal instant, `frame_alternation` earlier where the log row
        that first reads it is odd, plus a delay uniform in [0, frame_jitter)."""
        cfg, t = self.sim.cfg, count * self.period
        if cfg.frame_alternation > 0:
            row = math.ceil(t * cfg.log_hz - 1e-9)
            t -= cfg.frame_alternation * (row % 2)
        if cfg.frame_jitter > 0:
            t += float(self._timing.uniform(0.0, cfg.frame_jitter))
        return t

    def film(self, on_frame: Callable[[float, np.ndarray], None]) -> None:
        """Hand every frame the tracker gets, whole, to `on_frame(t, rgb)` (a camera video):
        eager and without windows (the same results: tested), so each frame not dropped is
        rendered and processed whole when it is taken. The poses are the same bit for bit; the
        health then counts every frame, where a lazy run skips those it never needed."""
        self.on_frame, self.lazy, self.windows = on_frame, False, False

    # -- the `Hook` lifecycle: tracking at the command rate ------------------------------------
    def initialize_episode(self, sim: ChainSim) -> None:
        if self._episode_rng is None:
            raise ValueError("a CameraChain run as an episode hook needs its rng= (the imaging "
                             "stream's seed)")
        self.start(self._episode_rng)

    def on_tick(self, sim: ChainSim) -> None:
        self.capture(sim)

    def finalize_episode(self, sim: ChainSim, keep: bool) -> None:
        self.close()

    def capture(self, sim: ChainSim) -> None:
        """Take a frame of the current state: its draws now, its processing now or later."""
        self.frames += 1
        draw = imaging.draw_frame(self.episode, self.noise, self.rng)
        if draw is None:                 # lost: the frame before stands until this clears it
            self.sync()
            self.dropped += 1
            self._detected[:] = False
            return
        jitter = self._jitter(sim)
        if self._waiting is None and self.lazy:
            spare = self._spare
            mujoco.mj_copyData(spare, sim.model, sim.data)
            self._waiting = _Frame(spare, sim.time, sim.poses, draw, jitter)
            return
        det = self._detect(sim.data, sim.time, draw)
        if not det.detected.all():       # the waiting frame's detections show through
            self.sync()
        self._waiting = None
        self._apply(det, sim.time, sim.poses, jitter)

    def _jitter(self, sim: ChainSim) -> np.ndarray | None:
        """This frame's marker jitter (n, 2), the Head's (row 0) scaled by its own share; None
        without jitter (no draw, so such a scenario's stream is unchanged)."""
        sigma = sim.cfg.marker_jitter
        if not sigma > 0:
            return None
        jitter = self.rng.normal(0.0, sigma, (len(self._latest), 2))
        jitter[0] *= sim.cfg.head_jitter_scale       # x 1.0 leaves every bit as it was
        return jitter

    def sync(self) -> None:
        """Process the waiting frame, if any (every read of the tracker does this first)."""
        if self._waiting is not None:
            f, self._waiting = self._waiting, None
            self._apply(self._detect(f.data, f.time, f.draw), f.time, f.truth, f.jitter)

    @property
    def latest(self) -> np.ndarray:
        """(n, 3) latest tracked pose per robot (x, y, θ), NaN before its first detection."""
        self.sync()
        return self._latest

    @property
    def latest_time(self) -> np.ndarray:
        self.sync()
        return self._latest_time

    @property
    def latest_truth(self) -> np.ndarray:
        """(n, 3) true pose of each robot when `latest` was seen: the tracker's own error is
        `latest - latest_truth`, whereas `latest - sim.poses` adds the motion since then."""
        self.sync()
        return self._latest_truth

    @property
    def detected(self) -> np.ndarray:
        self.sync()
        return self._detected

    @property
    def windowed(self) -> int:
        """Frames processed in windows around the robots rather than whole."""
        self.sync()
        return self._windowed

    @property
    def rendered(self) -> int:
        """Frames rendered: those taken, less the dropped ones and those never needed."""
        self.sync()
        return self._rendered

    def regions(self, t: float) -> list[tuple[int, int, int, int]] | None:
        """Pixel windows (x0, y0, x1, y1) around every robot's last detection for a frame at
        time `t`, or None for the whole frame (a robot was missed in the last processed frame,
        or windows are off)."""
        if not (self.windows and self._detected.all()):
            return None
        tracker, sim = self.tracker, self.sim
        z = sim.world.marker_height
        uv = tracker.camera.world_to_pixel(np.column_stack(
            [self._placed, np.full(len(self._placed), z)]))
        elapsed = max(t - self._seen_at, self.period)
        reach = sim.world.top_speed * elapsed * tracker.camera.px_per_m
        half = tracker.marker_radius_px + reach + 2
        h, w = self.renderer.height, self.renderer.width
        return [(max(0, int(u - half)), max(0, int(v - half)),
                 min(w, int(np.ceil(u + half))), min(h, int(np.ceil(v + half)))) for u, v in uv]

    def _detect(self, data: mujoco.MjData, t: float, draw: FrameDraw) -> Detections:
        """Render the state in `data`, put it through the imaging chain and track it."""
        rgb = self.renderer.render(data)
        self._rendered += 1
        rects = self.regions(t)
        if rects is None:
            frame = imaging.apply_chain(rgb, self.episode, draw)
            if self.on_frame is not None:
                self.on_frame(t, frame)
            return self.tracker.track(frame)
        self._windowed += 1
        return self.tracker.track_regions(imaging.regions(rgb, self.episode, draw, rects))

    def _apply(self, det: Detections, t: float, truth: np.ndarray,
               jitter: np.ndarray | None) -> None:
        seen = det.detected
        if self.health is not None:      # the tracker's own error: before the jitter
            self.health.add(seen, det.poses, truth, self._camera_at)
        self._placed[seen] = det.poses[seen, :2]
        self._latest[seen] = det.poses[seen]
        if jitter is not None:
            self._latest[seen, :2] += jitter[seen]
        if self._offset is not None:     # the marker's offset, turning with the body
            self._latest[seen, :2] += from_frame(self._offset[seen], np.zeros(2), truth[seen, 2])
        self._latest_time[seen] = t
        self._latest_truth[seen] = truth[seen]
        self._detected[:] = det.detected
        self._seen_at = t

    def close(self) -> None:
        self._waiting = None
        self.conditions.restore()
        self.renderer.close()
