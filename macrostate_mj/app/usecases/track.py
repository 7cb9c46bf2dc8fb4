"""Library API of `macrostate-mj track`: the simulator's tracker on recorded footage.

A lab makes its real datasets with the tracker its simulated ones came from: the scenario gives
the world (marker colours, sizes, plane), the camera at its nominal pose with the calibrated lens,
and `vision.trackers.tracker_for` the tracker of that world (colour triangles or ArUco tags, as
its markers say), the camera chain's own. Each frame of the video is tracked; the output is
`poses.parquet` in the simulator's layout (one row per frame and robot, the truth columns NaN:
there is none), the ThymioLoc instances at the scenario's log rate (`instances.csv`) and a
manifest.

Frame times: each frame's presentation time in the container (`simulate --camera-video` stamps
the time it was taken, so a dropped frame leaves a gap and a re-encode that keeps the stamps keeps
the times), checked against the sidecar `FILE.times.csv` when it is beside the video (whose exact
times are then used), else against the scenario's frame rate; `--times FILE` or `--fps F` (frame
index / F) override both. A recording whose times cannot be trusted is refused, as is a
`--robots` its frames contradict (`vision.team`): either would track every robot and be wrong.
As the online logger, a robot missed in a frame keeps its last tracked pose with `detected`
False (NaN before its first detection).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from macrostate_mj.chain.scenario import ScenarioConfig
from macrostate_mj.chain.scenarios import ResolvesScenario
from macrostate_mj.chain.world import validate_chain
from macrostate_mj.core.errors import RunFailure, UserError
from macrostate_mj.core.io import check_writable_dir
from macrostate_mj.core.run import Run
from macrostate_mj.formats.thymioloc import DEFAULT_PX_PER_CM

if TYPE_CHECKING:
    from macrostate_mj.chain.world import World
    from macrostate_mj.vision.aruco import ArucoTracker
    from macrostate_mj.vision.tracker import Tracker

PRODUCTS = ["poses.parquet", "instances.csv"]
TIME_TOLERANCE = 0.25   # of a frame period: how far a frame's time may stray from another
#                         account of it (a wrong one is off by a whole period or more; MKV
#                         rounds to 1 ms)
SEEK_GAP = 64           # frames: nearer than this, decode on rather than seek to a key frame
# A dropped frame the times hide (`hidden_drop`): robots moving steadily, at least MIN_STEP (m)
# a frame with speeds before and after within STEADY of their mean, all going DROP_RATIO times
# their speed's way across one pair of frames.
MIN_STEP = 0.003
STEADY = 0.3
DROP_RATIO = 1.6


@dataclass(frozen=True)
class TrackRequest(ResolvesScenario):
    video: Path
    scenario: ScenarioConfig     # a name or a file is resolved on construction
    robots: int
    out: Path
    overwrite: bool = False
    px_per_cm: float = DEFAULT_PX_PER_CM
    times: Path | None = None    # a frame,t file that overrides the video's own times
    fps: float | None = None     # frame index / fps as the times, overriding the video's


@dataclass(frozen=True)
class Container:
    """What the video file says of itself: its frame count, size, nominal fps, and each frame's
    presentation stamp (`pts`, in `time_base` units, in presentation order; None when the
    container holds none or they repeat)."""

    frames: int
    size: tuple[int, int]
    fps: float
    pts: np.ndarray | None
    time_base: float

    @property
    def stamps(self) -> np.ndarray | None:
        """Each frame's presentation time (s), or None."""
        return None if self.pts is None else self.pts * self.time_base


@dataclass(frozen=True)
class Footage:
    """What the checks learnt of the video: its frame count, size, fps, the frame times used
    and where they came from (`timing`: sidecar, video, --times or --fps)."""

    frames: int
    size: tuple[int, int]
    fps: float
    times: np.ndarray
    timing: str = "sidecar"


def check_request(req: TrackRequest) -> tuple[ScenarioConfig, Footage]:
    """Every check of a track request, before anything is built or written: the team and the
    scenario, the video's size, its frame times and the team its frames show."""
    from macrostate_mj.chain.filmed import check_filmed

    cfg = req.scenario
    validate_chain(cfg, req.robots, 1.0)
    check_filmed(cfg, req.robots)     # markers the tracker can tell apart, tags it can read
    if req.px_per_cm <= 0:
        raise UserError(f"--px-per-cm must be positive, got {req.px_per_cm}")
    if req.fps is not None and not (isinstance(req.fps, int | float) and math.isfinite(req.fps)
                                    and req.fps > 0):
        raise UserError(f"--fps must be a positive frame rate, got {req.fps!r}", "fps")
    if req.fps is not None and req.times is not None:
        raise UserError("give --times FILE or --fps F, not both", "times")
    if req.times is not None and not Path(req.times).is_file():
        raise UserError(f"--times {req.times} does not exist; give a frame,t file", "times")
    video = probe(req.video)
    want = tuple(cfg.camera.resolution)
    padded = tuple(-(-side // 2) * 2 for side in want)    # H.264 writers pad odd sides
    if video.size not in (want, padded):
        raise UserError(f"{req.video} has {video.size[0]} x {video.size[1]} frames but "
                        f"scenario {cfg.name}'s camera is {want[0]} x {want[1]}; give the "
                        "scenario of the camera that filmed it")
    times, timing = frame_times(req, cfg, video)
    check_team(req, cfg, video)
    _run(req, cfg).claim()
    return cfg, Footage(video.frames, video.size, video.fps, times, timing)


def probe(video: Path) -> Container:
    """Open the video, count its frames and read their presentation stamps (demuxing only)."""
    import av

    if not Path(video).is_file():
        raise UserError(f"video {video} does not exist; give a recorded video file")
    try:
        with av.open(str(video)) as container:
            if not container.streams.video:
                raise UserError(f"{video} holds no video stream; give a recorded video")
            stream = container.streams.video[0]
            size = (stream.codec_context.width, stream.codec_context.height)
            fps = float(stream.average_rate or 0)
            time_base = float(stream.time_base or 0)
            pts = [packet.pts for packet in container.demux(stream) if packet.size]
    except av.FFmpegError as err:
        raise UserError(f"cannot read video {video} ({err.strerror or err}); give an MP4 or "
                        "another video ffmpeg decodes") from None
    if not pts:
        raise UserError(f"video {video} has no frames; give a recorded video")
    stamps = None
    if time_base > 0 and None not in pts:
        stamps = np.sort(np.array(pts, np.int64))
        if len(stamps) > 1 and not np.all(np.diff(stamps) > 0):
            stamps = None                 # two frames at one time: no times to trust
    return Container(len(pts), size, fps, stamps, time_base)


def frame_times(req: TrackRequest, cfg: ScenarioConfig, video: Container
                ) -> tuple[np.ndarray, str]:
    """The times of the video's frames and where they come from: --times, --fps, else the
    sidecar (checked against the container's stamps), else the stamps (checked against the
    scenario's frame rate). Refuses, in one line, times that cannot be trusted."""
    from viz.video import times_path

    n, name = video.frames, req.video
    if req.times is not None:
        times = read_times(Path(req.times))
        if len(times) != n:
            raise UserError(f"--times {req.times} lists {len(times)} frame times but {name} has "
                            f"{n} frames; give the times file of this video", "times")
        return times, "--times"
    if req.fps is not None:
        return np.arange(n) / float(req.fps), "--fps"
    period, stamps, sidecar = 1 / cfg.camera_hz, video.stamps, times_path(name)
    redo = "give --times FILE (columns frame,t) or --fps F (frame index / F)"
    if sidecar.is_file():
        times = read_times(sidecar)
        if len(times) != n:
            raise UserError(f"{sidecar} lists {len(times)} frame times but {name} has {n} "
                            f"frames; give the times file of this video or remove it, or "
                            f"{redo}")
        if stamps is not None:
            off = np.abs((stamps - stamps[0]) - (times - times[0])) > TIME_TOLERANCE * period
            i = int(np.argmax(off))                       # the first frame that disagrees
            if off[i]:
                raise UserError(
                    f"{name}'s frame times disagree with {sidecar.name}: frame {i} is "
                    f"{stamps[i] - stamps[0]:.3f} s after the first in the video, "
                    f"{times[i] - times[0]:.3f} s in the times file (stamped evenly, as a "
                    "re-encode or a camera video from before frames carried their times is, or "
                    f"another video's file?); give --times {sidecar} to trust the file, or --fps F")
        return times, "sidecar"
    if stamps is None:
        raise UserError(f"{name} holds no frame times and has no {sidecar.name} beside it; "
                        f"{redo}")
    gaps = np.diff(stamps)
    if len(gaps):
        typical = float(np.median(gaps))
        stray = np.abs(gaps - np.maximum(np.round(gaps / period), 1) * period)
        i = int(np.argmax(stray))
        if abs(typical / period - 1) > TIME_TOLERANCE:
            raise UserError(f"{name}'s frames are {typical:.3g} s apart but scenario {cfg.name} "
                            f"films at {cfg.camera_hz:g} Hz (every {period:.3g} s), and no "
                            f"{sidecar.name} is beside it: its times cannot be trusted "
                            f"(re-encoded at another rate?); {redo}")
        if stray[i] > TIME_TOLERANCE * period + cfg.frame_jitter:
            raise UserError(f"{name}'s frame {i + 1} comes {gaps[i]:.3g} s after the one "
                            f"before, not a whole number of scenario {cfg.name}'s frame "
                            f"periods ({period:.3g} s), and no {sidecar.name} is beside it: "
                            f"its times cannot be trusted; {redo}")
    return stamps, "video"


def check_team(req: TrackRequest, cfg: ScenarioConfig, video: Container) -> None:
    """Refuse a --robots that a sample of the video's frames contradicts (`vision.team`)."""
    import mujoco

    from macrostate_mj.chain.world import build_world
    from macrostate_mj.vision.team import SAMPLES, check_team_shown

    world = build_world(cfg, req.robots)
    data = mujoco.MjData(world.model)
    mujoco.mj_forward(world.model, data)           # the camera at its nominal pose
    check_team_shown(world, data, sample_frames(req.video, video, SAMPLES), str(req.video))


def sample_frames(video: Path, container: Container, count: int) -> list[np.ndarray]:
    """`count` frames spread evenly over the video (RGB, cropped to its size): decoded on where
    the next is near, else sought from the key frame before it by its stamp."""
    import av

    frames = container.frames
    wanted = np.unique(np.linspace(0, frames - 1, min(count, frames)).round().astype(int))
    w, h = container.size
    pts, got, at = container.pts, [], -1
    try:
        with av.open(str(video)) as source:
            stream = source.streams.video[0]
            decoded: Iterator | None = None
            for i in wanted:
                if pts is not None and (decoded is None or i - at > SEEK_GAP):
                    source.seek(int(pts[i]), stream=stream, backward=True)
                    decoded, at = source.decode(stream), -1
                elif decoded is None:
                    decoded = source.decode(stream)
                for frame in decoded:
                    at = at + 1 if frame.pts is None or pts is None else \
                        int(np.searchsorted(pts, frame.pts))
                    if at >= i:
                        got.append(np.ascontiguousarray(
                            frame.to_ndarray(format="rgb24")[:h, :w]))
                        break
    except av.FFmpegError as err:
        raise UserError(f"cannot decode video {video} ({err.strerror or err}); give a video "
                        "ffmpeg decodes") from None
    return got


def read_times(path: Path) -> np.ndarray:
    """The `t` column of a `frame,t` CSV, checked to increase."""
    lines = path.read_text().splitlines()
    if not lines or lines[0].strip() != "frame,t":
        raise UserError(f"{path} is not a frame-times file (header frame,t); fix or remove it")
    try:
        times = np.array([float(line.split(",")[1]) for line in lines[1:] if line.strip()])
    except (IndexError, ValueError):
        raise UserError(f"{path} has a row that is not frame,t numbers; fix or remove it") \
            from None
    if not (np.all(np.isfinite(times)) and np.all(np.diff(times) > 0)):
        raise UserError(f"{path}: frame times must be finite and increasing; fix or remove it")
    return times


def frames_rgb(video: Path, size: tuple[int, int]) -> Iterator[np.ndarray]:
    """The video's frames, RGB uint8, in order, cropped to the camera's (width, height) `size`
    (an odd side was padded by the writer); PyAV: the decoder of the writer, quiet. A frame
    that does not decode ends the run in one line (the frames before are tracked and kept)."""
    import av

    w, h = size
    try:
        with av.open(str(video)) as container:
            for frame in container.decode(video=0):
                yield np.ascontiguousarray(frame.to_ndarray(format="rgb24")[:h, :w])
    except av.FFmpegError as err:
        raise RunFailure(f"video {video} stops decoding ({err.strerror or err}); the frames "
                         "before it were tracked") from None


def track_frames(tracker, frames: Iterator[np.ndarray], n: int,
                 progress: Callable[[int], None] | None = None) -> dict[str, np.ndarray]:
    """Track each frame; per frame the latest pose of each robot (kept through a miss, NaN
    before its first detection), when it was seen (frame index) and whether it was seen."""
    latest, seen_at = np.full((n, 3), np.nan), np.full(n, -1)
    tracked, seen_idx, detected = [], [], []
    for i, rgb in enumerate(frames):
        det = tracker.track(rgb)
        latest[det.detected] = det.poses[det.detected]
        seen_at[det.detected] = i
        tracked.append(latest.copy())
        seen_idx.append(seen_at.copy())
        detected.append(np.asarray(det.detected, bool).copy())
        if progress is not None:
            progress(i + 1)
    return {"tracked": np.asarray(tracked).reshape(-1, n, 3),
            "seen": np.asarray(seen_idx).reshape(-1, n),
            "detected": np.asarray(detected).reshape(-1, n)}


def log_rows(times: np.ndarray, log_hz: float) -> np.ndarray:
    """Per log tick (from the first frame, every 1/log_hz s), the last frame at or before it."""
    ticks = times[0] + np.arange(int(np.floor((times[-1] - times[0]) * log_hz + 1e-9)) + 1) \
        / log_hz
    return np.searchsorted(times, ticks + 1e-9, side="right") - 1


def hidden_drop(tracked: np.ndarray, detected: np.ndarray, times: np.ndarray
                ) -> tuple[int, float] | None:
    """A dropped frame the times do not show, or None: the first pair of frames (k, k + 1)
    across which every robot that moves steadily (at least `MIN_STEP` a frame, its speeds over
    the pairs before and after within `STEADY` of each other; two robots or more) went
    `DROP_RATIO` times or more the way its speed gives, with that least ratio. A dropped frame
    makes every such robot travel two periods in one; a robot starting or stopping moves alone
    (measured: a 150 s lab recording with 25 dropped frames, stamped evenly, flagged at 15 of
    them, at 1.93-1.97; its true times never above 1.06)."""
    ok = detected[1:] & detected[:-1]
    step = np.linalg.norm(tracked[1:, :, :2] - tracked[:-1, :, :2], axis=-1)
    dt = np.diff(times)
    if len(dt) < 3:
        return None
    speed = np.where(ok, step / dt[:, None], np.nan)
    before, after, mid = speed[:-2], speed[2:], speed[1:-1]
    usual = (before + after) / 2
    with np.errstate(invalid="ignore", divide="ignore"):
        steady = (usual * np.median(dt) > MIN_STEP) & (np.abs(before - after) < STEADY * usual)
        ratio = np.where(steady, mid / usual, np.inf).min(axis=1)
    flagged = np.flatnonzero((steady.sum(axis=1) >= 2) & (ratio >= DROP_RATIO))
    return None if not len(flagged) else (int(flagged[0]) + 1, float(ratio[flagged[0]]))


def track_video(req: TrackRequest, progress: Callable[[int], None] | None = None,
                checked: tuple[ScenarioConfig, Footage] | None = None) -> dict[str, Path]:
    """Track the video; returns the written paths. Nothing is written if validation fails.
    `checked`: what `check_request(req)` returned, when the caller ran it already."""
    import mujoco

    from macrostate_mj.chain.world import build_world
    from macrostate_mj.formats.instances import (
        cut_instances,
        instance_starts,
        to_thymioloc_pixels,
    )
    from macrostate_mj.formats.poses import poses_table, write_poses
    from macrostate_mj.formats.thymioloc import write_csv
    from macrostate_mj.vision.trackers import tracker_for

    cfg, footage = check_request(req) if checked is None else checked
    out = check_writable_dir(req.out)
    with _run(req, cfg) as run:
        with run.stage("build"):
            world = build_world(cfg, req.robots)
            data = mujoco.MjData(world.model)
            mujoco.mj_forward(world.model, data)       # the camera at its nominal pose
            tracker = tracker_for(world, data)
        with run.stage("track"):
            frames = frames_rgb(req.video, tuple(cfg.camera.resolution))
            got = track_frames(tracker, frames, req.robots, progress)
        if len(got["tracked"]) == 0:
            raise RunFailure(f"no frame of {req.video} decodes; check the file")
        times, n = footage.times[:len(got["tracked"])], req.robots
        drop = hidden_drop(got["tracked"], got["detected"], times)
        if drop is not None:
            k, ratio = drop
            raise UserError(
                f"{req.video}: between frames {k} and {k + 1} ({times[k]:.3f} and "
                f"{times[k + 1]:.3f} s by the times from {footage.timing}) every robot moving "
                f"steadily went {ratio:.1f}x the way its speed before and after gives: a "
                "dropped frame the times do not show (a re-encode that stamped its frames "
                "evenly?); give the recording's own times with --times FILE.times.csv, or "
                "track the original video")
        nan = np.full((len(times), n, 3), np.nan)
        when = np.where(got["seen"] >= 0, times[np.maximum(got["seen"], 0)], np.nan)
        table = poses_table(world.names, times, nan, np.full((len(times), 2), np.nan),
                            {"tracked": got["tracked"], "tracked_time": when,
                             "tracked_truth": nan, "detected": got["detected"]})
        written = {"poses": out / "poses.parquet", "instances": out / "instances.csv"}
        write_poses(written["poses"], table)
        logged = got["tracked"][log_rows(times, cfg.log_hz)]
        cut = cut_instances(logged, instance_starts(len(logged), cfg.log_hz))
        cut = cut[np.all(np.isfinite(cut), axis=(1, 2, 3))]    # a robot not seen yet: skip
        if len(cut):
            write_csv(written["instances"], to_thymioloc_pixels(cut, cfg.arena, req.px_per_cm))
        else:
            del written["instances"]
        written["manifest"] = run.path
        share = got["detected"].mean(axis=0) if len(times) else np.zeros(n)
        shares = {name: round(float(s), 4) for name, s in zip(world.names, share, strict=True)}
        run.record(robots=world.names, frames=len(times), frames_in_video=footage.frames,
                   frame_times=footage.timing, instances=len(cut), px_per_cm=req.px_per_cm,
                   detected_share=shares, outputs={k: str(v) for k, v in written.items()})
        missed = {k: v for k, v in shares.items() if v < cfg.tracking.min_detected}
        if missed:        # footage has no truth: a robot seldom seen is the one sign left
            raise RunFailure(missed_line(world, tracker, got, missed, cfg) +
                             f"; poses kept in {out}")
    return written


def missed_line(world: World, tracker: Tracker | ArucoTracker, got: dict[str, np.ndarray],
                missed: dict[str, float], cfg: ScenarioConfig) -> str:
    """Why the robot seen least was missed, in one line: its marker (colour or tag id) and the
    likeliest cause: never seen (the team or the lab), hidden (an obstacle or a wall stands
    between it and the camera where it was last seen), else blur or image quality."""
    from macrostate_mj.chain.tags import ArucoMarkers
    from macrostate_mj.vision.occlusion import occluded, scene_occluders

    name = min(missed, key=missed.get)
    r, share, n = world.names.index(name), missed[name], len(world.names)
    markers = cfg.markers
    marker = (f"ArUco tag {r} of {markers.dictionary}" if isinstance(markers, ArucoMarkers)
              else f"colour marker (hue {_hue(world.colours[r])} of 256, one of {n})")
    head = (f"robot {name}'s {marker} detected in {share:.1%} of the frames (limit "
            f"{cfg.tracking.min_detected:.0%}; {len(missed)} of {n} robots under it)")
    miss = ~got["detected"][:, r]
    last = got["tracked"][miss, r]                        # where it was when it went missing
    last = last[np.all(np.isfinite(last), axis=1)]
    hidden = occluded(last, world.marker_height, tracker.camera.position,
                      scene_occluders(cfg), world.marker_outline).mean() if len(last) else 0.0
    if share == 0:
        cause = (f"team size or lab: its marker never shows (is --robots {n} the team filmed "
                 f"and {cfg.name} its lab, its markers, camera and lens?)")
    elif hidden >= 0.5:
        cause = (f"occlusion: in {hidden:.0%} of its misses it was last seen where an obstacle "
                 "or a wall stands between its marker and the camera")
    elif len(missed) > n / 2:
        cause = ("blur or image quality across the footage: focus, exposure, motion blur, or "
                 f"another camera than {cfg.name}'s (its resolution, height and lens)")
    else:
        cause = ("blur or a covered marker: it was in the camera's clear view when missed "
                 "(motion blur, glare, or a marker partly covered or worn)")
    return f"{head}; likeliest cause {cause}"


def _hue(rgb: np.ndarray) -> int:
    from macrostate_mj.chain.markers import marker_hues

    return int(marker_hues(np.atleast_2d(rgb))[0])


def detected_line(manifest: Path) -> str:
    """The per-robot detected shares of a finished track, in one line."""
    import json

    record = json.loads(Path(manifest).read_text())
    shares = record.get("detected_share", {})
    return ", ".join(f"{k} {shares[k]:.1%}" for k in record.get("robots", shares))  # chain order


def _run(req: TrackRequest, cfg: ScenarioConfig) -> Run:
    identity = {"video": str(req.video), "robots": req.robots, "px_per_cm": req.px_per_cm}
    if req.times is not None:
        identity["times"] = str(req.times)
    if req.fps is not None:
        identity["fps"] = req.fps
    return Run(req.out, "track", {"request": identity, "scenario": asdict(cfg)}, None,
               PRODUCTS, req.overwrite)
