"""Tracker accuracy and speed, and collection throughput, against limits measured in the run."""

from __future__ import annotations

import time

import cv2
import numpy as np

from macrostate_mj.app.bench.sim import _best_of, figure, record_commands, replay_bare
from macrostate_mj.chain.scenarios import get_scenario
from macrostate_mj.chain.sim import ChainSim, Every
from macrostate_mj.chain.world import build_world
from macrostate_mj.core.angles import wrap_angle
from macrostate_mj.vision.camera import OverheadRenderer
from macrostate_mj.vision.camera_chain import CameraChain


def bench_tracker(episodes: int = 6, seconds: float = 30.0, robots: int = 5) -> list[dict]:
    """Accuracy at default imaging noise over several episodes (each its own draw of light and
    camera error; every frame, every robot), and tracker time per 750 x 570 frame on one core
    against one bare full-frame colour conversion."""
    world = build_world(get_scenario("lab"), robots)
    sim = ChainSim(world)
    chain = CameraChain(sim)
    pos, head, seen, frames = [], [], [], []

    def check(s: ChainSim) -> None:
        dropped = chain.dropped
        chain.capture(s)
        if chain.dropped > dropped:
            return
        truth, ok = s.poses(), chain.detected
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
               limit_name="one bare cv2.cvtColor RGB->HSV of the frame, 1 core"),
    ]


def bench_collect(minutes: float = 1.0, robots: int = 3) -> list[dict]:
    """One worker's collection (physics, policy, render, noise, tracker, log) against bare
    `mj_step` replaying the same commands plus bare renders of the same frames."""
    from collectors.episodes import EpisodeSpec, run_episode

    spec = EpisodeSpec("lab", robots, minutes * 60, 10.0, 0, 0)
    run_episode(EpisodeSpec("lab", robots, 5.0, 0.0, 0, 0))      # warm-up (imports, GL)
    t0 = time.perf_counter()
    _, _, stats = run_episode(spec)
    t_ours = time.perf_counter() - t0

    cfg = get_scenario("lab")
    world = build_world(cfg, robots)
    start, ticks = record_commands(ChainSim(world), spec.warmup + spec.seconds, spec.rng(0))
    t0 = time.perf_counter()
    data = replay_bare(world.model, start, ticks, stats["steps"])
    t_phys = time.perf_counter() - t0
    with OverheadRenderer(world.model) as renderer:
        renderer.render(data)
        t0 = time.perf_counter()
        for _ in range(stats["frames"]):
            renderer.render(data)
        t_render = time.perf_counter() - t0
    sim_min = (spec.warmup + spec.seconds) / 60
    tag = f"lab, {robots} robots, 1 worker, {stats['frames']} frames"
    return [
        figure("collect_sim_minutes_per_wall_minute", sim_min / (t_ours / 60), "x",
               sim_min / ((t_phys + t_render) / 60),
               limit_name="bare mj_step + bare renders of the same frames", config=tag),
        figure("collect_render_share_of_limit", t_render / (t_phys + t_render), "fraction",
               config=tag),
    ]
