"""The vision tracker against ground truth, on rendered frames through the imaging chain."""

import mujoco
import numpy as np
import pytest

from macrostate_mj.chain.scenarios import get_scenario
from macrostate_mj.chain.sim import ChainSim, Every
from macrostate_mj.chain.world import build_world, marker_area
from macrostate_mj.core.angles import wrap_angle
from macrostate_mj.core.frames import to_frame
from macrostate_mj.vision.camera import OverheadRenderer, PinholeCamera
from macrostate_mj.vision.camera_chain import CameraChain
from macrostate_mj.vision.imaging import NoiseConfig, degrade, draw_episode
from macrostate_mj.vision.tracker import Tracker


def errors_over_run(seconds: float, seed: int, noise: NoiseConfig, jitter: float = 0.0):
    """The tracker's own errors (mm, degrees) and detections, by default without the lab's
    marker jitter: the image pipeline alone."""
    world = build_world(get_scenario("lab").with_overrides(marker_jitter=jitter), 5)
    sim = ChainSim(world)
    sim.reset(np.random.default_rng(seed))
    chain = CameraChain(sim, noise)
    chain.start(np.random.default_rng([seed, 1]))
    pos, head, seen = [], [], []

    def check(s: ChainSim) -> None:
        frames = chain.frames
        chain.capture(s)
        if chain.frames == frames or chain.dropped and not chain.detected.any():
            return
        truth = s.poses
        ok = chain.detected
        seen.append(ok)
        pos.extend(np.linalg.norm(chain.latest[ok, :2] - truth[ok, :2], axis=1))
        head.extend(np.abs(wrap_angle(chain.latest[ok, 2] - truth[ok, 2])))

    try:
        sim.run(seconds, [Every(0.25, check)])
    finally:
        chain.close()
    return np.array(pos) * 1000, np.degrees(head), np.concatenate(seen)


def test_tracker_accuracy_at_default_noise():
    pos_mm, head_deg, seen = errors_over_run(40.0, seed=2, noise=NoiseConfig(drop_prob=0.0))
    assert np.median(pos_mm) <= 3.0 and np.percentile(pos_mm, 95) <= 8.0
    assert np.median(head_deg) <= 2.0
    assert seen.mean() >= 0.995


def test_clean_frames_give_sub_pixel_accuracy():
    pos_mm, head_deg, seen = errors_over_run(10.0, seed=4, noise=NoiseConfig.none())
    assert np.max(pos_mm) < 3.3                         # below one pixel (3.3 mm)
    assert np.median(head_deg) < 1.5 and seen.all()


def test_marker_jitter_adds_its_noise_to_every_tracked_position():
    """With marker jitter sigma, each axis of the tracked position errs by about
    sqrt(sigma^2 + the image pipeline's own error^2), and the heading is left alone."""
    noise = NoiseConfig(drop_prob=0.0)
    base_mm, base_deg, _ = errors_over_run(20.0, seed=6, noise=noise)
    pos_mm, head_deg, _ = errors_over_run(20.0, seed=6, noise=noise, jitter=0.005)
    # the norm of a 2-D error with per-axis sigma s has RMS s * sqrt(2)
    base_axis = np.sqrt(np.mean(base_mm**2) / 2)
    axis = np.sqrt(np.mean(pos_mm**2) / 2)
    assert axis == pytest.approx(np.hypot(5.0, base_axis), rel=0.1)
    assert np.median(head_deg) == pytest.approx(np.median(base_deg), abs=0.5)


def filmed(seconds: float, seed: int, scenario: str = "lab", robots: int = 3,
           noise: NoiseConfig | None = None, windows: bool = True, **overrides
           ) -> tuple[np.ndarray, CameraChain]:
    """Every frame's tracked poses (frames, n, 3) of a run with these scenario overrides, and
    the (closed) camera chain that filmed it."""
    world = build_world(get_scenario(scenario).with_overrides(**overrides), robots)
    sim = ChainSim(world)
    sim.reset(np.random.default_rng(seed))
    chain = CameraChain(sim, noise, windows=windows)
    chain.start(np.random.default_rng([seed, 1]))
    seen = []

    def take(s: ChainSim) -> None:
        chain.capture(s)
        seen.append(chain.latest.copy())

    try:
        sim.run(seconds, [Every(chain.period, take)])
    finally:
        chain.close()
    return np.array(seen), chain


def test_the_heads_jitter_scales_alone():
    """`head_jitter_scale` scales the Head's marker jitter and nothing else: the other robots'
    tracks are bit for bit those of scale 1, and the Head's jitter is the scale's share of it."""
    quiet = NoiseConfig(drop_prob=0.0)
    one, half, none = (filmed(6.0, 3, noise=quiet, marker_jitter=0.005, head_jitter_scale=k)[0]
                       for k in (1.0, 0.5, 0.0))
    assert np.array_equal(one[:, 1:], half[:, 1:]) and np.array_equal(one[:, 1:], none[:, 1:])
    jitter = one[:, 0, :2] - none[:, 0, :2]
    assert np.sqrt(np.mean(jitter**2)) == pytest.approx(0.005, rel=0.3)
    assert np.allclose(half[:, 0, :2] - none[:, 0, :2], 0.5 * jitter, atol=1e-12)
    assert np.array_equal(one, filmed(6.0, 3, noise=quiet, marker_jitter=0.005)[0])


def frame_and_tracker(start: np.ndarray):
    world = build_world(get_scenario("lab"), len(start))
    sim = ChainSim(world)
    sim.reset(np.random.default_rng(0), start=start)
    cam = PinholeCamera.from_model(world.model, sim.data)
    tracker = Tracker(cam, world.colours, world.marker_height,
                      marker_area(world.spec, "H/marker"))
    with OverheadRenderer(world.model) as renderer:
        rgb = renderer.render(sim.data)
    return sim, cam, tracker, rgb


def test_robots_touching_each_other_and_a_wall():
    start = np.array([[0.0, 0.0, 0.3], [-0.115, 0.0, 0.0], [1.19, 0.5, 1.57]])
    sim, _, tracker, rgb = frame_and_tracker(start)
    det = tracker.track(rgb)
    assert det.detected.all()
    assert np.abs(det.poses[:, :2] - sim.poses[:, :2]).max() < 0.004
    assert np.abs(wrap_angle(det.poses[:, 2] - sim.poses[:, 2])).max() < np.radians(3)


def test_partial_occlusion_and_lost_markers():
    start = np.array([[0.0, 0.0, 0.0], [-0.4, 0.0, 0.0], [-0.8, 0.0, 0.0]])
    sim, cam, tracker, rgb = frame_and_tracker(start)
    z = sim.world.marker_height
    (u0, v0), (u1, v1), _ = np.round(cam.world_to_pixel(
        np.column_stack([sim.poses[:, :2], np.full(3, z)]))).astype(int)
    occluded = rgb.copy()
    occluded[v0 - 20:v0 + 20, u0 + 8:u0 + 30] = 180       # covers the Head's apex third
    occluded[v1 - 20:v1 + 20, u1 - 30:u1 + 20] = 180      # covers F1's marker entirely
    det = tracker.track(occluded)
    assert det.detected.tolist() == [True, False, True]
    assert np.linalg.norm(det.poses[0, :2] - sim.poses[0, :2]) < 0.02
    assert abs(wrap_angle(det.poses[0, 2])) < np.radians(10)


def test_imaging_noise_is_seeded_and_drops_frames():
    rgb = np.full((60, 80, 3), 128, np.uint8)
    cfg = NoiseConfig()
    a = degrade(rgb, draw_episode(cfg, np.random.default_rng(1), rgb.shape), cfg,
                np.random.default_rng(2))
    b = degrade(rgb, draw_episode(cfg, np.random.default_rng(1), rgb.shape), cfg,
                np.random.default_rng(2))
    assert np.array_equal(a, b) and not np.array_equal(a, rgb)
    dropping = NoiseConfig(drop_prob=1.0)
    assert degrade(rgb, draw_episode(dropping, np.random.default_rng(1), rgb.shape), dropping,
                   np.random.default_rng(2)) is None


@pytest.mark.parametrize("shift", [0.0, 0.002])
def test_camera_error_unknown_to_the_tracker_biases_it(shift):
    """The calibration is nominal: a physically shifted camera shows up as tracking error."""
    world = build_world(get_scenario("lab"), 2)
    sim = ChainSim(world)
    sim.reset(np.random.default_rng(0), start=np.array([[0.0, 0, 0], [-0.4, 0, 0]]))
    cam = PinholeCamera.from_model(world.model, sim.data)
    tracker = Tracker(cam, world.colours, world.marker_height, marker_area(world.spec, "H/marker"))
    world.model.cam_pos[world.model.camera("overhead").id, 0] += shift
    mujoco.mj_forward(world.model, sim.data)
    with OverheadRenderer(world.model) as renderer:
        det = tracker.track(renderer.render(sim.data))
    err = det.poses[0, 0] - sim.poses[0, 0]
    assert err == pytest.approx(-shift, abs=0.001)    # the scene appears shifted the other way


@pytest.mark.parametrize(("scenario", "robots", "seed", "log_phase"),
                         [("lab", 3, 8, 0.1), ("lab", 5, 9, 0.3), ("webots", 4, 10, 0.0),
                          ("robotarium", 5, 11, 0.02)])
def test_lazy_filming_gives_the_same_log(scenario, robots, seed, log_phase):
    """Frames rendered only when their result can be read give the eager log bit for bit,
    misses and drops included (a high drop rate makes both happen), and skip frames."""
    from macrostate_mj.chain.sim import PoseLog

    logs, rendered = [], []
    noise = NoiseConfig(drop_prob=0.1)
    for lazy in (False, True):
        world = build_world(get_scenario(scenario), robots)
        sim = ChainSim(world)
        sim.reset(np.random.default_rng(seed))
        chain = CameraChain(sim, noise, lazy=lazy)
        chain.start(np.random.default_rng([seed, 1]))
        log = PoseLog(world.names, tracker=chain)
        period = 1 / world.scenario.log_hz
        try:
            sim.run(12.0, [Every(chain.period, chain.capture),
                           Every(period, log.append, log_phase)])
        finally:
            chain.close()
        logs.append(log.tracked_arrays())
        rendered.append((chain.rendered, chain.frames, chain.dropped))
    for key in ("tracked", "tracked_time", "tracked_truth", "detected"):
        assert np.array_equal(logs[0][key], logs[1][key], equal_nan=key != "detected")
    assert np.isfinite(logs[0]["tracked"][4:]).all()
    (eager, frames, dropped), (lazy, _, _) = rendered
    assert dropped > 0 and eager == frames - dropped
    if period > chain.period:            # a log slower than the camera leaves frames unread
        assert lazy < 0.75 * eager


@pytest.mark.parametrize(("scenario", "robots", "seed"),
                         [("lab", 3, 11), ("lab", 5, 12), ("webots", 6, 13),
                          ("robotarium", 5, 14)])
def test_windows_around_the_robots_track_exactly_as_the_whole_frame(scenario, robots, seed):
    """The windowed path (imaging and tracking only around each robot's last detection) gives
    the same poses, bit for bit, as processing every whole frame; and it is the path taken."""
    def run(windows: bool) -> tuple[np.ndarray, int, int]:
        poses, chain = filmed(15.0, seed, scenario, robots, windows=windows)
        return poses, chain.windowed, chain.frames

    (whole, none, _), (windowed, used, frames) = run(False), run(True)
    assert none == 0 and used >= 0.9 * frames
    assert np.array_equal(whole, windowed, equal_nan=True)


def test_the_chain_on_crops_matches_the_whole_frame():
    """`imaging.regions`: random windows anywhere (frame edges included), every episode draw
    (blur, lens, noise offset, JPEG quality): the same pixels as the whole frame's chain."""
    from macrostate_mj.vision import imaging

    world = build_world(get_scenario("lab"), 5)
    sim = ChainSim(world)
    sim.reset(np.random.default_rng(3))
    sim.run(3.0, [])
    with OverheadRenderer(world.model) as r:
        rgb = r.render(sim.data)
    cfg = NoiseConfig(blur_px=3.0)
    for seed in range(25):
        rng = np.random.default_rng(seed)
        ep = draw_episode(cfg, rng, rgb.shape)
        draw = imaging.FrameDraw(tuple(int(v) for v in rng.integers(0, imaging.FIELD_MARGIN, 2)))
        full = imaging.apply_chain(rgb, ep, draw)
        corners = rng.integers(0, [750, 570], size=(8, 2))
        rects = [(int(u), int(v), int(min(750, u + rng.integers(4, 160))),
                  int(min(570, v + rng.integers(4, 160)))) for u, v in corners]
        for x0, y0, img in imaging.regions(rgb, ep, draw, rects):
            assert np.array_equal(img, full[y0:y0 + img.shape[0], x0:x0 + img.shape[1]]), (
                seed, x0, y0)


def test_frames_at_their_own_rate_with_a_timing_jitter_are_seeded_and_in_order():
    """`frame_hz` and `frame_jitter`: frames are taken at the camera's own rate, each delayed
    by up to the jitter after its nominal instant (on whole physics steps), from a stream of
    their own: the same seed gives the same frames, and the 2 Hz log then holds frames of
    uneven age. Without them the camera keeps the command rate."""
    from macrostate_mj.chain.sim import PoseLog

    cfg = get_scenario("lab").with_overrides(frame_hz=3.0, frame_jitter=0.1)

    def frame_times(cfg, seed):
        sim = ChainSim(build_world(cfg, 3))
        sim.reset(np.random.default_rng(seed))
        chain = CameraChain(sim, rng=np.random.default_rng([seed, 1]), lazy=False)
        taken = []
        capture = chain.capture
        chain.capture = lambda s: (taken.append(s.time), capture(s))
        log = PoseLog(sim.world.names, tracker=chain)
        sim.episode(12.0, [chain, Every(0.5, log.append, 0.1)])
        return np.array(taken), log.tracked_arrays()

    times, log = frame_times(cfg, 5)
    gaps = np.diff(times)
    assert np.all(gaps > 1 / 3 - 0.1 - 1e-9) and np.all(gaps < 1 / 3 + 0.1 + 1e-9)
    assert gaps.std() > 0.02                       # not a steady rate
    assert len(times) == pytest.approx(12 * 3, abs=1)
    again, log_again = frame_times(cfg, 5)
    assert np.array_equal(times, again)
    assert np.array_equal(log["tracked"], log_again["tracked"], equal_nan=True)
    ages = (np.arange(len(log["tracked_time"])) * 0.5 + 0.1)[:, None] - log["tracked_time"]
    assert np.nanstd(ages[2:, 0]) > 0.03
    steady, _ = frame_times(get_scenario("lab"), 5)
    assert np.allclose(np.diff(steady), 0.25)


def test_robots_that_differ_wheels_and_markers_drawn_per_episode_from_the_seed():
    """`wheel_spread`: each wheel's effective radius (the speed factor of its commanded rate)
    drawn per episode from a child of the reset stream (the same seed, the same wheels; none
    without it; the wheels' shapes untouched); `marker_offset`: each robot's tracked point sits
    off its centre by a fixed vector that turns with the body."""
    cfg = get_scenario("lab").with_overrides(wheel_spread=0.03, marker_offset=0.005,
                                             marker_jitter=0.0)   # the offset alone
    sim = ChainSim(build_world(cfg, 3))
    shapes = sim.model.geom_size.copy()
    sim.reset(7)
    first = sim._wheel_gain.copy()
    sim.reset(7)
    assert np.array_equal(first, sim._wheel_gain)
    assert np.array_equal(shapes, sim.model.geom_size)
    assert len(set(first.ravel().round(6))) == 6 and np.all(np.abs(first - 1) <= 0.09)
    top = sim.model.actuator_ctrlrange[sim.world.ctrl_left, 1] / first[:, 0]
    assert np.allclose(top, sim.world.max_wheel_speed)     # a larger wheel is faster at full
    plain = ChainSim(build_world(get_scenario("lab"), 3))
    plain.reset(7)
    assert plain._wheel_gain is None
    assert np.all(plain.model.actuator_ctrlrange[:, 1] == plain.world.max_wheel_speed)

    chain = CameraChain(sim, rng=np.random.default_rng([7, 1]), lazy=False)
    seen = []
    sim.reset(7)
    sim.episode(10.0, [chain, Every(0.5, lambda s: seen.append(
        (chain.latest.copy(), chain.latest_truth.copy())), 0.3)])
    tracked, truth = (np.array(a)[4:] for a in zip(*seen, strict=True))
    body = to_frame(tracked[..., :2][..., None, :], truth[..., :2], truth[..., 2])[..., 0, :]
    offset = np.median(body, axis=0)                 # per robot, in its body frame
    assert np.all(np.abs(body - offset).max(axis=0) < 0.004)     # fixed on the body
    assert np.abs(offset).max() > 0.002


def test_rows_that_alternate_read_frames_of_two_ages_shared_by_every_robot():
    """`frame_alternation`: the camera in step with the log, the frames every other row reads
    taken that much earlier; each row's tracked time (every robot's the same) is its own
    instant or that much before it, alternating, so the rows' intervals alternate as the real
    ThymioLoc rows' do. A scenario refuses an alternation the frames have no room for."""
    from macrostate_mj.chain.sim import PoseLog
    from macrostate_mj.core.errors import UserError

    cfg = get_scenario("lab").with_overrides(frame_alternation=0.05)
    sim = ChainSim(build_world(cfg, 3))
    sim.reset(np.random.default_rng(4))
    chain = CameraChain(sim, NoiseConfig(drop_prob=0.0), rng=np.random.default_rng([4, 1]))
    log = PoseLog(sim.world.names, tracker=chain)
    sim.episode(10.0, [chain, Every(0.5, log.append, sim.log_phase)])
    rows = np.asarray(log.times)
    seen = log.tracked_arrays()["tracked_time"]
    ages = np.round(rows[:, None] - seen, 6)
    assert np.all(ages == ages[:, :1])                      # shared by the row's robots
    k = np.arange(len(rows))
    assert np.allclose(ages[:, 0], np.where(k % 2, 0.05, 0.0), atol=sim.model.opt.timestep)
    assert np.allclose(np.diff(seen[:, 0]), np.where(k[1:] % 2, 0.45, 0.55),
                       atol=2 * sim.model.opt.timestep)
    with pytest.raises(UserError, match="frame_alternation"):
        get_scenario("lab").with_overrides(frame_alternation=0.25)
