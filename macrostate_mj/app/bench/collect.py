"""Tracker accuracy and speed, and collection throughput, against limits measured in the run."""

from __future__ import annotations

import os
import tempfile
import time
from pathlib import Path

import cv2
import mujoco
import numpy as np

from macrostate_mj.app.bench import SUITES, figure
from macrostate_mj.app.bench.sim import _best_of, best_of_pair, record_commands, replay_bare
from macrostate_mj.chain.scenarios import SCENARIOS
from macrostate_mj.chain.sim import ChainSim, Every
from macrostate_mj.chain.world import build_world
from macrostate_mj.core.angles import wrap_angle
from macrostate_mj.vision.camera import OverheadRenderer
from macrostate_mj.vision.camera_chain import CameraChain
from macrostate_mj.vision.tracker import Detections


@SUITES.register("tracker", rank=40)
def bench_tracker(episodes: int = 6, seconds: float = 30.0, robots: int = 5) -> list[dict]:
    """Accuracy at default imaging noise over several episodes (each its own draw of light and
    camera error; every frame, every robot), and tracker time per 750 x 570 frame on one core
    against one bare full-frame colour conversion. The image pipeline alone: the lab's marker
    jitter is drawn noise, not the tracker's."""
    world = build_world(SCENARIOS["lab"].with_overrides(marker_jitter=0.0), robots)
    sim = ChainSim(world)
    chain = CameraChain(sim)
    pos, head, seen, frames = [], [], [], []

    def check(s: ChainSim) -> None:
        dropped = chain.dropped
        chain.capture(s)
        if chain.dropped > dropped:
            return
        truth, ok = s.poses, chain.detected
        seen.append(ok.copy())
        pos.extend(np.linalg.norm(chain.latest[ok, :2] - truth[ok, :2], axis=1))
        head.extend(np.abs(wrap_angle(chain.latest[ok, 2] - truth[ok, 2])))
        if len(frames) < 40:
            frames.append(chain.renderer.render(s.data))

    try:
        for ep in range(episodes):
            sim.reset(np.random.default_rng(ep))
            chain.start(np.random.default_rng([ep, 1]))
            sim.run(seconds, [Every(0.25, check)])
    finally:
        chain.close()
    pos_mm, head_deg = np.array(pos) * 1000, np.degrees(head)
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        t_track = _best_of(lambda: [chain.tracker.track(f) for f in frames]) / len(frames)
        t_bare = _best_of(lambda: [cv2.cvtColor(f, cv2.COLOR_RGB2HSV_FULL) for f in frames]
                          ) / len(frames)
    finally:
        cv2.setNumThreads(threads)
    tag = f"lab, {robots} robots, {episodes} episodes, {len(seen)} frames, default noise"
    return [
        figure("tracker_position_error_median", float(np.median(pos_mm)), "mm", config=tag,
               target="<= 3"),
        figure("tracker_position_error_p95", float(np.percentile(pos_mm, 95)), "mm",
               config=tag, target="<= 8"),
        figure("tracker_heading_error_median", float(np.median(head_deg)), "deg", config=tag,
               target="<= 2"),
        figure("tracker_detection_rate", float(np.mean(np.concatenate(seen))), "fraction",
               config=tag, target=">= 0.995"),
        figure("tracker_ms_per_frame", t_track * 1000, "ms", config="750x570, 1 core",
               target="<= 3"),
        figure("tracker_frames_per_s", 1 / t_track, "frames/s", 1 / t_bare,
               config="750x570 whole frames, 1 core",
               limit_name="one bare cv2.cvtColor RGB->HSV of the frame, 1 core"),
    ]


@SUITES.register("health", rank=50)
def bench_health(seconds: float = 30.0, robots: int = 5) -> list[dict]:
    """What the tracking health costs: a tracked run of the lab (physics, camera chain, pose
    log) with its health figures against the same run without them, best of alternated runs.
    One camera chain serves both (its renderer made once: a GL context's start-up varies more
    than the figure). Target: at most 5 % slower (ratio >= 0.95)."""
    from macrostate_mj.chain.sim import PoseLog

    world = build_world(SCENARIOS["lab"], robots)
    sim = ChainSim(world)
    chain = CameraChain(sim)
    monitor = chain.health

    def tracked(health: bool) -> PoseLog:
        chain.health = monitor if health else None
        sim.reset(np.random.default_rng(0))
        chain.start(np.random.default_rng([0, 1]))
        log = PoseLog(world.names, tracker=chain)
        sim.run(seconds, [chain, Every(1 / sim.cfg.log_hz, log.append, sim.log_phase)])
        chain.sync()
        if health:                   # the frames' figures and the dataset rows'
            monitor.report(log).judged(sim.cfg)
        return log

    spent = [0.0]                       # the health's own seconds, counted call by call
    add = monitor.add

    def counted_add(*args: object) -> None:
        t0 = time.perf_counter()
        add(*args)
        spent[0] += time.perf_counter() - t0

    try:
        ours, bare = best_of_pair(lambda: tracked(True), lambda: tracked(False), repeats=7)
        monitor.add = counted_add
        t0 = time.perf_counter()
        log = tracked(True)
        whole = time.perf_counter() - t0
        t0 = time.perf_counter()
        monitor.report(log).judged(sim.cfg)
        spent[0] += time.perf_counter() - t0
    finally:
        chain.close()
    config = f"lab, {robots} robots, {seconds:g} s tracked, default noise"
    return [figure("tracked_run_with_health_s", ours, "s", bare, lower_is_better=True,
                   config=config, limit_name="the same tracked run without health figures",
                   target="ratio >= 0.95"),
            figure("health_share_of_tracked_run", spent[0] / whole, "fraction", config=config,
                   target="<= 0.05", counted="every HealthMonitor.add, then report (frames and "
                   "rows) and judge")]


def _bare_limit(args: tuple) -> None:
    """One worker's limit: bare `mj_step` replaying the episode's recorded commands, with a
    bare render of the state at `frames` of its camera ticks (spread evenly), at the same
    settings (same scene, size, offsamples, threads)."""
    spec, steps, frames, start, ticks = args
    world = build_world(spec.scenario, spec.robots)
    filmed = np.zeros(len(ticks), bool)
    filmed[np.linspace(0, len(ticks) - 1, frames).round().astype(int)] = True
    with OverheadRenderer(world.model) as renderer:
        replay_bare(world.model, start, ticks, steps,
                    lambda k, data: renderer.render(data) if filmed[k] else None)


def _recorded(spec) -> tuple:
    """The episode's start state and wheel commands, recorded before any timing starts."""
    world = build_world(spec.scenario, spec.robots)
    return record_commands(ChainSim(world), spec.warmup + spec.seconds, spec.rng(0))


def _stages(spec, frames: int = 60) -> dict[str, float]:
    """Seconds per frame of each stage on one worker, timed apart on frames of the episode."""
    from collectors.episodes import run_episode
    from macrostate_mj.formats.poses import write_poses
    from macrostate_mj.vision import imaging

    world = build_world(spec.scenario, spec.robots)
    sim = ChainSim(world)
    sim.reset(spec.rng(0))
    chain = CameraChain(sim, spec.noise, rng=spec.rng(1))
    chain.initialize_episode(sim)
    rgbs = []
    per_tick = int(round(1 / (sim.cfg.command_hz * sim.model.opt.timestep)))
    t0 = time.perf_counter()
    for _ in range(frames):
        sim.command()
        mujoco.mj_step(sim.model, sim.data, nstep=per_tick)
    t_phys = (time.perf_counter() - t0) / frames
    ep, cfg, rng = chain.episode, chain.noise, np.random.default_rng(0)
    t0 = time.perf_counter()
    for _ in range(frames):
        rgbs.append(chain.renderer.render(sim.data))
    t_render = (time.perf_counter() - t0) / frames
    steps = {"motion_blur": lambda im: cv2.filter2D(im, -1, ep.blur_kernel)
             if ep.blur_kernel is not None else im,
             "lens_psf": lambda im: cv2.sepFilter2D(im, -1, ep.psf, ep.psf),
             "sensor_noise": lambda im: ep.sensor_field.add_to(im, 0, 0),
             "jpeg": lambda im: imaging.jpeg_round_trip(im, ep.jpeg_quality)}
    out = {"physics": t_phys, "render": t_render}
    # the usual path: every robot seen two frames before (the frame between never needed), so
    # only windows around them are processed
    chain._apply(Detections(sim.poses, np.ones(len(sim.poses), bool)), sim.time, sim.poses, None)
    rects, draw = chain.regions(sim.time + 2 * chain.period), imaging.FrameDraw((0, 0))
    parts = [imaging.regions(im, ep, draw, rects) for im in rgbs]
    out["imaging_in_windows"] = _best_of(
        lambda: [imaging.regions(im, ep, draw, rects) for im in rgbs]) / frames
    out["tracking_in_windows"] = _best_of(
        lambda: [chain.tracker.track_regions(p) for p in parts]) / frames
    # the whole frame, after a miss or a dropped frame: each step of the chain
    for name, fn in steps.items():
        out[f"imaging_{name}_full_frame"] = _best_of(lambda fn=fn: [fn(im) for im in rgbs]
                                                     ) / frames
    degraded = [imaging.degrade(im, ep, cfg, rng) for im in rgbs]
    degraded = [im for im in degraded if im is not None]
    out["tracking_full_frame"] = _best_of(lambda: [chain.tracker.track(im) for im in degraded]
                                          ) / len(degraded)
    chain.finalize_episode(sim, True)
    _, table, stats = run_episode(spec)
    with tempfile.TemporaryDirectory() as tmp:
        out["writing"] = _best_of(lambda: write_poses(Path(tmp) / "p.parquet", table)
                                  ) / stats["frames"]
    return out


@SUITES.register("collect", rank=60)
def bench_collect(minutes: float = 1.0, robots: int = 3, repeats: int = 3) -> list[dict]:
    """Collection throughput against its limit (bare `mj_step` replaying the same commands
    plus bare renders of every frame the camera takes, at the same settings), for 1 and 2
    workers; the overhead against bare renders of only the frames the lazy camera chain renders
    (the strict limit); and the cost of each stage in ms per frame and as a share of one
    worker's wall time."""
    from collectors.episodes import EpisodeSpec, run_episode
    from macrostate_mj.core.parallel import local_results, render_threads

    figures: list[dict] = []
    lab = SCENARIOS["lab"]
    run_episode(EpisodeSpec(lab, robots, 5.0, 0.0, 0, 0))      # warm-up (imports, GL)
    for workers in (1, 2):
        specs = [EpisodeSpec(lab, robots, minutes * 60, 10.0, 0, i) for i in range(workers)]
        recorded = {s.index: _recorded(s) for s in specs}
        t_ours = t_limit = t_strict = np.inf
        for _ in range(repeats):       # alternated, best of each: the least disturbed runs
            t0 = time.perf_counter()
            results = list(local_results(run_episode, specs, workers))
            t_ours = min(t_ours, time.perf_counter() - t0)
            by_index = {i: stats for i, _, stats in results}
            tasks = [(s, by_index[s.index]["steps"], by_index[s.index]["frames"],
                      *recorded[s.index]) for s in specs]
            t0 = time.perf_counter()
            list(local_results(_bare_limit, tasks, workers))
            t_limit = min(t_limit, time.perf_counter() - t0)
            strict = [(s, steps, by_index[s.index]["rendered"], *rest)
                      for s, steps, _, *rest in tasks]
            t0 = time.perf_counter()
            list(local_results(_bare_limit, strict, workers))
            t_strict = min(t_strict, time.perf_counter() - t0)
        frames = sum(by_index[s.index]["frames"] for s in specs)
        sim_min = sum(s.warmup + s.seconds for s in specs) / 60
        threads = os.environ.get("LP_NUM_THREADS",
                                 render_threads(workers) if workers > 1 else "all cores")
        rendered = sum(by_index[s.index]["rendered"] for s in specs)
        windowed = sum(by_index[s.index]["windowed"] for s in specs)
        tag = (f"lab, {robots} robots, {workers} worker(s), {frames} camera frames, "
               f"{rendered} rendered ({windowed} in windows; the rest never read), llvmpipe "
               f"threads per worker: {threads}, best of {repeats}")
        figures.append(figure(f"collect_sim_minutes_per_wall_minute_{workers}w",
                              sim_min / (t_ours / 60), "x", sim_min / (t_limit / 60),
                              limit_name="bare mj_step + bare renders of every camera frame, "
                              "same workers", config=tag))
        figures.append(figure(f"collect_ms_per_frame_{workers}w", t_ours / frames * 1000, "ms",
                              t_limit / frames * 1000, config=tag, lower_is_better=True,
                              limit_name="bare physics + render per frame"))
        figures.append(figure(f"collect_overhead_{workers}w", t_ours, "s", t_strict,
                              config=tag, lower_is_better=True,
                              limit_name="bare mj_step + bare renders of only the frames "
                              "rendered"))
        if workers == 1:
            wall_1w, rendered_1w = t_ours / frames, rendered / frames
    for name, sec in _stages(EpisodeSpec(SCENARIOS["lab"], robots, 30.0, 0.0, 0, 0)).items():
        per_frame = name in ("physics", "writing")    # the rest: per rendered frame
        share = sec * (1 if per_frame else rendered_1w) / wall_1w
        figures.append(figure(f"collect_stage_{name}_ms_per_frame", sec * 1000, "ms",
                              config=f"lab, {robots} robots, 1 worker, each stage timed apart, "
                              f"per {'camera' if per_frame else 'rendered'} frame",
                              share_of_wall=round(share, 4)))
    return figures
