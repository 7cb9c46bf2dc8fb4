"""The overhead camera chain as a periodic hook: render -> imaging noise -> tracker.

It keeps the latest detection of every robot (and when it was made), as the real testbed's
logger did: the 2 Hz pose log records whatever the 4 Hz tracker saw last, up to one command
period earlier (`t_trk` in the log says exactly when). A robot missed in a frame keeps its previous
tracked pose (NaN before its first detection) with `detected` False.

Where every robot was seen in the previous frame, imaging and tracking run only in a window
around each (`regions`): the window holds the marker wherever the robot can have driven in one
period, and `imaging.regions` makes its pixels exactly as the whole frame's chain would. After
a miss or a dropped frame, or with `windows=False`, the whole frame is processed.
"""

from __future__ import annotations

from concurrent.futures import Future, ThreadPoolExecutor

import mujoco
import numpy as np

from macrostate_mj.chain.sim import ChainSim
from macrostate_mj.vision import imaging
from macrostate_mj.vision.camera import OverheadRenderer
from macrostate_mj.vision.imaging import NoiseConfig, SceneConditions, draw_episode
from macrostate_mj.vision.tracker import Tracker


class CameraChain:
    """Owns a renderer; `start(rng)` once per episode, then `capture` at the command rate, then
    `close()`. As a `Hook` (given `rng`), `ChainSim.episode` makes those calls itself.

    With `pipelined`, the imaging chain and the tracker of one frame run on a helper thread
    (OpenCV releases the GIL) while the physics moves on; reading `latest`, `latest_time`,
    `detected`, `frames` or `dropped` waits for the frame in flight first. Frames are still
    processed in order, with the same draws, so the results are identical either way.
    """

    def __init__(self, sim: ChainSim, noise: NoiseConfig | None = None, pipelined: bool = False,
                 rng: np.random.Generator | None = None, phase: float = 0.0,
                 windows: bool = True):
        self.sim = sim
        self.period, self.phase = 1 / sim.cfg.command_hz, phase     # a `Hook`: command rate
        self._episode_rng = rng
        self._pool = ThreadPoolExecutor(1) if pipelined else None
        self._pending: Future | None = None
        self.noise = noise or NoiseConfig()
        self.renderer = OverheadRenderer(sim.model)
        self.conditions = SceneConditions(sim.model)
        world = sim.world
        n = len(world.names)
        self._latest = np.full((n, 3), np.nan)
        self._latest_time = np.full(n, np.nan)     # when each robot was last seen (s)
        self._latest_truth = np.full((n, 3), np.nan)   # its true pose at that moment
        self._detected = np.zeros(n, bool)
        self._frames = self._dropped = self._windowed = 0
        self.windows = windows

    def start(self, rng: np.random.Generator) -> None:
        """Calibrate on the nominal camera, then draw this episode's conditions."""
        self.sync()
        sim = self.sim
        self.conditions.restore()
        mujoco.mj_forward(sim.model, sim.data)
        self.tracker = Tracker.for_world(sim.world, sim.data)
        self.rng = rng
        shape = (self.renderer.height, self.renderer.width, 3)
        self.episode = draw_episode(self.noise, rng, shape)
        self.conditions.apply(self.episode)
        mujoco.mj_forward(sim.model, sim.data)
        self._latest[:] = np.nan
        self._latest_time[:] = np.nan
        self._latest_truth[:] = np.nan
        self._detected[:] = False

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
        rgb = self.renderer.render(sim.data)         # GL work stays on this thread
        if self._pool is None:
            self._process(rgb, sim.time, sim.poses)
            return
        self.sync()
        self._pending = self._pool.submit(self._process, rgb, sim.time, sim.poses)

    def sync(self) -> None:
        """Wait for the frame in flight (pipelined mode); a no-op otherwise."""
        if self._pending is not None:
            pending, self._pending = self._pending, None
            pending.result()

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
    def frames(self) -> int:
        self.sync()
        return self._frames

    @property
    def dropped(self) -> int:
        self.sync()
        return self._dropped

    @property
    def windowed(self) -> int:
        """Frames processed in windows around the robots rather than whole."""
        self.sync()
        return self._windowed

    def regions(self) -> list[tuple[int, int, int, int]] | None:
        """Pixel windows (x0, y0, x1, y1) around every robot's last detection, or None for the
        whole frame (a robot was missed last frame, or windows are off)."""
        if not (self.windows and self._detected.all()):
            return None
        tracker, sim = self.tracker, self.sim
        z = sim.world.marker_height
        uv = tracker.camera.world_to_pixel(np.column_stack(
            [self._latest[:, :2], np.full(len(self._latest), z)]))
        reach = sim.world.top_speed * self.period * tracker.camera.px_per_m
        half = tracker.marker_radius_px + reach + 2
        h, w = self.renderer.height, self.renderer.width
        return [(max(0, int(u - half)), max(0, int(v - half)),
                 min(w, int(np.ceil(u + half))), min(h, int(np.ceil(v + half)))) for u, v in uv]

    def _process(self, rgb: np.ndarray, t: float, truth: np.ndarray) -> None:
        self._frames += 1
        draw = imaging.draw_frame(self.episode, self.noise, self.rng)
        if draw is None:
            self._dropped += 1
            self._detected[:] = False
            return
        rects = self.regions()
        if rects is None:
            det = self.tracker.track(imaging.apply_chain(rgb, self.episode, draw))
        else:
            self._windowed += 1
            det = self.tracker.track_regions(imaging.regions(rgb, self.episode, draw, rects))
        self._latest[det.detected] = det.poses[det.detected]
        self._latest_time[det.detected] = t
        self._latest_truth[det.detected] = truth[det.detected]
        self._detected[:] = det.detected

    def close(self) -> None:
        self.sync()
        if self._pool is not None:
            self._pool.shutdown()
        self.conditions.restore()
        self.renderer.close()
