"""Library API of `macrostate-mj track`: the simulator's tracker on recorded footage.

A lab makes its real datasets with the tracker its simulated ones came from: the scenario gives
the world (marker colours, sizes, plane), the camera at its nominal pose with the calibrated lens,
and `vision.trackers.tracker_for` the tracker of that world (colour triangles or ArUco tags, as
its markers say), the camera chain's own. Each frame of the video is tracked; the output is
`poses.parquet` in the simulator's layout (one row per frame and robot, the truth columns NaN:
there is none), the ThymioLoc instances at the scenario's log rate (`instances.csv`) and a
manifest.

Frame times come from the sidecar `FILE.times.csv` that `simulate --camera-video` writes (an
MP4's frame rate is nominal and a dropped frame is missing), else frame index / the video's fps.
As the online logger, a robot missed in a frame keeps its last tracked pose with `detected`
False (NaN before its first detection).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from macrostate_mj.chain.scenario import ScenarioConfig
from macrostate_mj.chain.scenarios import ResolvesScenario
from macrostate_mj.chain.world import validate_chain
from macrostate_mj.core.errors import RunFailure, UserError
from macrostate_mj.core.io import check_writable_dir
from macrostate_mj.core.run import Run
from macrostate_mj.formats.thymioloc import DEFAULT_PX_PER_CM

PRODUCTS = ["poses.parquet", "instances.csv"]


@dataclass(frozen=True)
class TrackRequest(ResolvesScenario):
    video: Path
    scenario: ScenarioConfig     # a name or a file is resolved on construction
    robots: int
    out: Path
    overwrite: bool = False
    px_per_cm: float = DEFAULT_PX_PER_CM


@dataclass(frozen=True)
class Footage:
    """What the checks learnt of the video: its frame count, size, fps and frame times."""

    frames: int
    size: tuple[int, int]
    fps: float
    times: np.ndarray


def check_request(req: TrackRequest) -> tuple[ScenarioConfig, Footage]:
    """Every check of a track request, before anything is built or written."""
    from macrostate_mj.chain.rendered import check_rendered_colours

    cfg = req.scenario
    validate_chain(cfg, req.robots, 1.0)
    check_rendered_colours(cfg, req.robots)      # markers the tracker can tell apart
    if req.px_per_cm <= 0:
        raise UserError(f"--px-per-cm must be positive, got {req.px_per_cm}")
    footage = probe(req.video)
    want = tuple(cfg.camera.resolution)
    padded = tuple(-(-side // 2) * 2 for side in want)    # H.264 writers pad odd sides
    if footage.size not in (want, padded):
        raise UserError(f"{req.video} has {footage.size[0]} x {footage.size[1]} frames but "
                        f"scenario {cfg.name}'s camera is {want[0]} x {want[1]}; give the "
                        "scenario of the camera that filmed it")
    _run(req, cfg).claim()
    return cfg, footage


def probe(video: Path) -> Footage:
    """Open the video, count its frames and read their times (sidecar, else index / fps)."""
    import av

    from viz.video import times_path

    if not Path(video).is_file():
        raise UserError(f"video {video} does not exist; give a recorded video file")
    try:
        with av.open(str(video)) as container:
            if not container.streams.video:
                raise UserError(f"{video} holds no video stream; give a recorded video")
            stream = container.streams.video[0]
            size = (stream.codec_context.width, stream.codec_context.height)
            fps = float(stream.average_rate or 0)
            frames = sum(1 for packet in container.demux(stream) if packet.size)
    except av.FFmpegError as err:
        raise UserError(f"cannot read video {video} ({err.strerror or err}); give an MP4 or "
                        "another video ffmpeg decodes") from None
    if frames == 0:
        raise UserError(f"video {video} has no frames; give a recorded video")
    sidecar = times_path(video)
    if sidecar.is_file():
        times = read_times(sidecar)
        if len(times) != frames:
            raise UserError(f"{sidecar} lists {len(times)} frame times but {video} has "
                            f"{frames} frames; give the times file of this video or remove it")
    elif fps > 0:
        times = np.arange(frames) / fps
    else:
        raise UserError(f"{video} states no frame rate and has no {sidecar.name} beside it; "
                        "add one (columns frame,t)")
    return Footage(frames, size, fps, times)


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


def track_video(req: TrackRequest, progress: Callable[[int], None] | None = None
                ) -> dict[str, Path]:
    """Track the video; returns the written paths. Nothing is written if validation fails."""
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

    cfg, footage = check_request(req)
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
                   instances=len(cut), px_per_cm=req.px_per_cm, detected_share=shares,
                   outputs={k: str(v) for k, v in written.items()})
        missed = {k: v for k, v in shares.items() if v < cfg.tracking.min_detected}
        if missed:        # footage has no truth: a robot seldom seen is the one sign left
            name = min(missed, key=missed.get)
            raise RunFailure(
                f"robot {name} detected in {missed[name]:.1%} of the frames (limit "
                f"{cfg.tracking.min_detected:.0%}; {len(missed)} robot(s) under it): is --robots "
                f"{req.robots} the team filmed (colour markers are chosen by team size) and the "
                f"scenario its lab? Poses kept in {out}")
    return written


def detected_line(manifest: Path) -> str:
    """The per-robot detected shares of a finished track, in one line."""
    import json

    record = json.loads(Path(manifest).read_text())
    shares = record.get("detected_share", {})
    return ", ".join(f"{k} {shares[k]:.1%}" for k in record.get("robots", shares))  # chain order


def _run(req: TrackRequest, cfg: ScenarioConfig) -> Run:
    identity = {"video": str(req.video), "robots": req.robots, "px_per_cm": req.px_per_cm}
    return Run(req.out, "track", {"request": identity, "scenario": asdict(cfg)}, None,
               PRODUCTS, req.overwrite)
