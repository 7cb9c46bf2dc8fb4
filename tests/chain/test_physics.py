"""Physics regression: what a roboticist checks before trusting a simulated robot."""

from pathlib import Path

import numpy as np
import pytest
from builders import drive

from macrostate_mj.chain.health import Fault, PhysicsError
from macrostate_mj.chain.motion import body_twist
from macrostate_mj.chain.parked import parked
from macrostate_mj.chain.physics_soak import soak, soak_tasks, summary
from macrostate_mj.chain.planners import FixedWaypoint
from macrostate_mj.chain.scenario import steps_per_tick
from macrostate_mj.chain.scenarios import SCENARIOS, get_scenario
from macrostate_mj.chain.sim import ChainSim, Every, PoseLog, simulate_poses
from macrostate_mj.chain.world import build_world
from macrostate_mj.core.angles import wrap_angle
from macrostate_mj.core.errors import UserError

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
    gaps = np.linalg.norm(np.diff(sim.poses[:, :2], axis=0), axis=1)
    assert sim.poses[0, 0] == pytest.approx(half[0], abs=0.07)
    assert np.all(np.abs(gaps - d) < 0.02), gaps
    assert np.all(np.abs(sim.poses[:, 1]) < 0.1)      # still on the line the Head drove


def test_a_parked_chain_of_robots_that_differ_stands_still():
    """Once the Head has parked, its chain settles and stays still, also with the rear rule
    and robot differences `sysid` fits (stiff gains, a start gap, wheels that differ, rear
    robots that stop rather than back off): a parked robot neither creeps nor turns on the
    spot. (Known and not judged here: in some 5-robot chains one robot, commanded to stand,
    creeps 0.2 mm/s and turns 0.3 deg/s; docs: decisions/sysid.)"""
    from dataclasses import replace

    from macrostate_mj.chain.motion import WaitForBehind

    base = get_scenario("lab")
    fitted = replace(base.with_overrides(k_f=1.63 * base.k_f, k_t=3.4 * base.k_t,
                                         k_omega=0.66 * base.k_omega, wheel_spread=0.0315),
                     followers=WaitForBehind(0.06, hold=base.spacing, start=0.011))
    for cfg, seeds in ((base, (0,)), (fitted, (0, 1, 2))):
        assert parked(cfg, 3, seeds).still, (cfg.k_f, seeds)
    # the check can fail: five such robots that back off at once from the robot ahead turn
    # on the spot (55 degrees in the minute watched), which `sysid` refuses
    backs_off = replace(fitted, followers=WaitForBehind(0.06))
    assert not parked(backs_off, 5).still
    # wheels that differ leave a parked robot upright: it neither creeps nor turns (wheels of
    # other sizes tilted it, and it crept up to 6 mm in 5 s)
    sim = ChainSim(build_world(fitted, 2), planner=FixedWaypoint((0.0, 0.0)))
    for seed in range(3):
        sim.reset(np.random.default_rng(seed), start=np.array([[0.0, 0, 0], [-0.3, 0, 0]]))
        stood = sim.poses.copy()
        sim.run(30.0, [])
        assert np.abs(sim.poses - stood).max() < 1e-4


# Invariants over seeds nobody tuned to (tuning used lab seeds 100-119 and 1000-1023 and
# robotarium 0-15):
# they hold on any CPU, where one long chaotic trajectory does not. Bounds sit above what the
# soak measured over 100-200 seeds x 600 s (max lift 0.6 mm, penetration 1.1 mm, tilt 9.3 deg).
# The suite keeps 52 seeds (its share of the 20-minute budget); the long soaks are `soak` runs.
SOAKS = [("lab", 3, 12), ("lab", 5, 12), ("lab", 7, 8), ("webots", 5, 12), ("robotarium", 6, 8)]


@pytest.mark.slow
@pytest.mark.parametrize("scenario,robots,seeds", SOAKS)
def test_many_seeds_never_tip_climb_escape_or_diverge(scenario, robots, seeds):
    runs = soak(soak_tasks(get_scenario(scenario), robots, seeds, 300.0, first_seed=5000),
                workers=2)
    row = summary(runs, workers=2)
    assert [r.reason for r in runs if r.fault] == []
    assert row["runs"] == seeds and row["warnings"] == 0
    assert row["max_lift_mm"] < 3.0
    assert row["max_penetration_mm"] < 1.5
    # A robot reversing hard into a neighbour can rest its nose on the floor (the shell's 8 mm
    # clearance: about 9 degrees, seen in webots); a tip is 30 degrees.
    assert row["max_tilt_deg"] < 15.0


def nudged_run(check_steps: int, hook) -> PhysicsError:
    """A lab run with `hook` fired at 2 Hz from t = 1 s; returns the fault it must raise."""
    world = build_world(get_scenario("lab"), 3)
    sim = ChainSim(world)
    sim.reset(np.random.default_rng(0))
    sim.check_steps = check_steps
    with pytest.raises(PhysicsError) as err:
        sim.run(10.0, [Every(0.5, hook, phase=1.0)])
    return err.value


def lift_tail(sim: ChainSim) -> None:
    sim.data.xfrc_applied[sim.monitor.body[-1], 2] = 4.0     # 4 N up on a 0.26 kg robot


@pytest.mark.parametrize("hook,fault", [
    (lift_tail, Fault.LIFT),
    (lambda s: s.data.qpos.__setitem__(s.world.qpos_adr[1], 5.0), Fault.ESCAPE),
    (lambda s: s.data.qvel.__setitem__(s.world.qvel_adr[0] + 3, np.nan), Fault.NAN),
])
def test_a_fault_is_caught_at_the_physics_step_where_it_happens(hook, fault):
    coarse = nudged_run(10**9, hook)           # checked after each stretch between events
    fine = nudged_run(1, hook)                 # checked after every physics step
    assert coarse.fault.fault == fault
    assert coarse.fault == fine.fault          # same robot, same step, same value
    assert coarse.fault.time < 1.25            # not at the end of the run


def test_every_embedded_rate_divides_into_whole_steps_and_others_are_refused():
    for name in SCENARIOS:
        cfg = get_scenario(name)
        dt = build_world(cfg, 3).model.opt.timestep
        assert dt == cfg.physics.timestep                  # the scenario's, compiled as it is
        for hz in (cfg.command_hz, cfg.log_hz):
            assert steps_per_tick(1 / hz, dt, name) * dt == pytest.approx(1 / hz)
    with pytest.raises(UserError, match="lab command period 0.333333 s .* whole steps"):
        get_scenario("lab").with_overrides(command_hz=3.0)     # refused when it is made


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
    _, log = simulate_poses(world, 10.0, seed=7)
    return log.arrays()[1]


def test_golden_trajectory_unchanged():
    """Fails when the physics changes. Regenerate on purpose with:
    .venv/bin/python tests/chain/golden/regenerate.py"""
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


def test_reset_takes_a_seed_or_a_generator_and_refuses_bad_ones_before_touching_the_state():
    sim = ChainSim(build_world(get_scenario("lab"), 4))
    sim.reset(7)
    seeded = sim.poses.copy()
    sim.reset(np.random.default_rng(7))
    assert np.array_equal(seeded, sim.poses)
    for rng, start, words in ((-1, None, "Generator or a whole number >= 0"),
                              ("7", None, "Generator"), (True, None, "Generator"),
                              (0, np.zeros((3, 3)), "shape"),
                              (0, np.full((4, 3), np.nan), "NaN"), (0, "x", "str"),
                              (0, np.full((4, 3), 9.0), "outside")):
        with pytest.raises(UserError, match=words):
            sim.reset(rng, start=start)
        assert np.array_equal(seeded, sim.poses)      # refused before any change


def test_robotarium_chain_moves_with_preset_head():
    world = build_world(get_scenario("robotarium"), 4)
    sim = ChainSim(world)
    sim.reset(np.random.default_rng(2))
    log = PoseLog(world.names)
    sim.run(30.0, [Every(1.0, log.append)])
    _, p, _ = log.arrays()
    travelled = np.linalg.norm(np.diff(p[:, :, :2], axis=0), axis=2).sum(0)
    assert np.all(travelled > 0.3)               # every robot follows, none is stuck
    gaps = np.linalg.norm(np.diff(p[-1, :, :2], axis=0), axis=1)
    assert np.all(gaps < 0.12)                   # within the 0.12 sensor radius (seed §2.5.2)
