"""Physics regression: what a roboticist checks before trusting a simulated robot."""

from pathlib import Path

import mujoco
import numpy as np
import pytest

from macrostate_mj.motion import body_twist, wrap_angle
from macrostate_mj.planners import FixedWaypoint
from macrostate_mj.scenarios import get_scenario
from macrostate_mj.sim import ChainSim, Periodic, PoseLog, simulate_poses
from macrostate_mj.world import build_world

GOLDEN = Path(__file__).parent / "golden" / "lab3_seed7.npz"


def lone_robot(scenario: str = "lab") -> tuple[ChainSim, int]:
    """A 2-robot world with the Tail parked far away: the Head drives alone."""
    cfg = get_scenario(scenario)
    half = np.array(cfg.arena) / 2
    world = build_world(cfg, 2)
    sim = ChainSim(world)
    start = [[-half[0] + 0.2, 0.0, 0.0], [half[0] - 0.1, half[1] - 0.1, 0.0]]
    sim.reset(np.random.default_rng(0), start=np.array(start))
    return sim, 0


def drive(sim: ChainSim, left: float, right: float, seconds: float) -> np.ndarray:
    """Hold wheel speeds on robot 0 and return its (x, y, theta) every physics step."""
    w = sim.world
    sim.data.ctrl[w.ctrl_left[0]] = left
    sim.data.ctrl[w.ctrl_right[0]] = right
    out = []
    for _ in range(int(round(seconds / sim.model.opt.timestep))):
        mujoco.mj_step(sim.model, sim.data)
        out.append(sim.poses()[0])
    return np.array(out)


@pytest.mark.parametrize("left,right", [(4.0, 4.0), (2.0, 5.0), (6.0, 3.0), (-3.0, 3.0)])
def test_wheel_speeds_give_differential_drive_kinematics(left, right):
    sim, _ = lone_robot()
    w = sim.world
    drive(sim, left, right, 1.0)                         # let the motors spin up
    traj = drive(sim, left, right, 2.0)
    dt = sim.model.opt.timestep
    heading = traj[:-1, 2]
    step = np.diff(traj[:, :2], axis=0)
    v = np.mean(step[:, 0] * np.cos(heading) + step[:, 1] * np.sin(heading)) / dt
    omega = np.mean(wrap_angle(np.diff(traj[:, 2]))) / dt
    v_ref, omega_ref = body_twist(left, right, w.wheel_radius, w.track)
    scale = max(abs(v_ref), abs(omega_ref) * w.track / 2)  # wheel rim speed: the 5 % basis
    assert abs(v - v_ref) <= 0.05 * scale
    assert abs(omega - omega_ref) * w.track / 2 <= 0.05 * scale


def test_straight_drive_reaches_top_speed_and_keeps_its_line():
    sim, _ = lone_robot()
    top = sim.world.max_wheel_speed
    traj = drive(sim, top, top, 8.0)
    start = traj[0, :2]
    travelled = traj[:, 0] - start[0]
    after_1m = np.argmax(travelled >= 1.0)
    assert after_1m > 0, "never drove 1 m"
    assert np.max(np.abs(traj[: after_1m + 1, 1] - start[1])) < 0.02
    speed = np.diff(traj[:, 0]) / sim.model.opt.timestep
    assert np.mean(speed[-200:]) == pytest.approx(sim.world.top_speed, rel=0.05)


@pytest.mark.parametrize("scenario", ["lab", "webots"])
def test_chain_behind_a_straight_head_settles_to_spacing(scenario):
    cfg = get_scenario(scenario)
    half = np.array(cfg.arena) / 2 - cfg.wall_margin
    n, d = 5, cfg.spacing
    start = np.array([[-half[0] + (n - 1 - i) * d, 0.0, 0.0] for i in range(n)])
    world = build_world(cfg, n)
    sim = ChainSim(world, planner=FixedWaypoint((half[0], 0.0)))
    sim.reset(np.random.default_rng(0), start=start)
    sim.run(60.0, [])
    gaps = np.linalg.norm(np.diff(sim.poses()[:, :2], axis=0), axis=1)
    assert sim.poses()[0, 0] == pytest.approx(half[0], abs=0.07)
    assert np.all(np.abs(gaps - d) < 0.02), gaps
    assert np.all(np.abs(sim.poses()[:, 1]) < 0.1)      # still on the line the Head drove


def test_thirty_minutes_stay_upright_finite_and_inside_the_walls():
    cfg = get_scenario("lab")
    world = build_world(cfg, 5)
    _, log = simulate_poses(world, 1800.0, seed=3)   # check_physics runs at every log tick
    _, poses, _ = log.arrays()
    assert np.all(np.isfinite(poses))
    half = np.array(cfg.arena) / 2
    assert np.all(np.abs(poses[:, :, 0]) < half[0]) and np.all(np.abs(poses[:, :, 1]) < half[1])
    assert len(poses) == 3600


def test_lab_statistics_are_of_the_order_of_the_real_testbed():
    """SPEC §3: spacing 31 +- 3 cm, Head 7-10 cm/s, |turn| 10-20 deg/s (3-robot runs)."""
    world = build_world(get_scenario("lab"), 3)
    _, log = simulate_poses(world, 600.0, seed=11)
    _, p, _ = log.arrays()
    spacing = np.linalg.norm(np.diff(p[:, :, :2], axis=1), axis=2) * 100
    speed = np.linalg.norm(np.diff(p[:, :, :2], axis=0), axis=2).mean(0) * 2 * 100
    turn = np.degrees(np.abs(wrap_angle(np.diff(p[:, :, 2], axis=0)))).mean(0) * 2
    assert 28 < spacing.mean() < 35
    assert 5 < speed[0] < 11 and speed[0] > speed[1] > speed[2] > 1.5
    assert np.all((turn > 5) & (turn < 25))


def golden_run() -> np.ndarray:
    world = build_world(get_scenario("lab"), 3)
    _, log = simulate_poses(world, 20.0, seed=7)
    return log.arrays()[1]


def test_golden_trajectory_unchanged():
    """Fails when the physics changes. Regenerate on purpose with:
    .venv/bin/python tests/golden/regenerate.py"""
    expected = np.load(GOLDEN)["poses"]
    got = golden_run()
    assert got.shape == expected.shape
    assert np.max(np.abs(got - expected)) < 1e-6


def test_same_seed_same_log_other_seed_different():
    world = build_world(get_scenario("lab"), 3)
    a = simulate_poses(world, 15.0, seed=5)[1].arrays()[1]
    b = simulate_poses(world, 15.0, seed=5)[1].arrays()[1]
    c = simulate_poses(world, 15.0, seed=6)[1].arrays()[1]
    assert np.array_equal(a, b)
    assert not np.allclose(a, c)


def test_robotarium_chain_moves_with_preset_head():
    world = build_world(get_scenario("robotarium"), 4)
    sim = ChainSim(world)
    sim.reset(np.random.default_rng(2))
    log = PoseLog(world.names)
    sim.run(30.0, [Periodic(1.0, log.append)])
    _, p, _ = log.arrays()
    travelled = np.linalg.norm(np.diff(p[:, :, :2], axis=0), axis=2).sum(0)
    assert np.all(travelled > 0.3)               # every robot follows, none is stuck
    gaps = np.linalg.norm(np.diff(p[-1, :, :2], axis=0), axis=1)
    assert np.all(gaps < 0.12)                   # within the 0.12 sensor radius (seed §2.5.2)
