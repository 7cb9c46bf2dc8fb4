"""The robot contract (`chain.robot`) and the e-puck, the third robot: every shipped robot meets
the contract, a file that breaks it is refused in one line naming the file and the broken item,
and the e-puck drives as its data sheet says and runs a chain without a physics fault."""

import mujoco
import numpy as np
import pytest
from builders import drive

from macrostate_mj.chain.markers import marker_colours, taken_for_marker
from macrostate_mj.chain.physics_soak import soak, soak_tasks, summary
from macrostate_mj.chain.robot import known_robots, load_robot
from macrostate_mj.chain.scenarios import SCENARIOS
from macrostate_mj.chain.sim import ChainSim
from macrostate_mj.chain.world import build_world
from macrostate_mj.core.angles import wrap_angle
from macrostate_mj.core.errors import UserError
from macrostate_mj.core.paths import ASSETS
from macrostate_mj.vision.tracker import Tracker

# The lab with e-pucks (until a scenario file holds one): the Thymio lab's rules at a spacing
# and speeds for a 70 mm robot whose top speed is 0.129 m/s.
EPUCK_LAB = SCENARIOS["lab"].with_overrides(
    robot="epuck", spacing=0.2, head_speed=0.06, chain_speed=0.129, avoid_radius=0.13,
    avoid_gain=0.1, reach_radius=0.04, wall_margin=0.12)
EPUCK = (ASSETS / "epuck" / "robot.xml").read_text()


def test_every_shipped_robot_meets_the_contract():
    assert {"thymio", "gritsbot", "epuck"} <= set(known_robots())
    for name in known_robots():
        load_robot(name, largest_team=100)          # raises on any broken item


# Each: what is changed in a copy of the e-puck file, and what the refusal must name.
BROKEN = {
    "no left motor": ('    <velocity name="wheel_left" class="drive" joint="wheel_left"/>\n', "",
                      "no actuator 'wheel_left'"),
    "no marker": ('<geom name="marker"', '<geom name="badge"',
                  "no geom 'marker' of mesh 'marker'"),
    "no root": ('<freejoint name="root"/>', '<freejoint name="base"/>',
                "no free joint named 'root'"),
    "green shell": ('rgba="0.86 0.86 0.84 1" contype="0"', 'rgba="0.1 0.8 0.1 1" contype="0"',
                    "visible geom 'shell' (rgba 0.1 0.8 0.1) would be tracked as marker"),
    "wheel hits robots": ('mass="0.008" friction',
                          'contype="2" conaffinity="2" mass="0.008" friction',
                          "geom 'wheel_left' must touch the floor only"),
    "dragging support": ('mass="0.002" priority="1"', 'mass="0.002"',
                         "geom 'support_front' rests on the floor beside the wheels"),
    "rough collider": ('contype="2" conaffinity="2" condim="1"', 'contype="2" conaffinity="2"',
                       "geom 'chassis' touches robots or walls"),
    "one-way motor": ('ctrlrange="-6.2832 6.2832"', 'ctrlrange="0 6.2832"',
                   "actuator 'wheel_left' needs a symmetric ctrlrange"),
}


@pytest.mark.parametrize("case", sorted(BROKEN))
def test_a_robot_file_that_breaks_the_contract_is_refused_naming_what_is_missing(case, tmp_path):
    old, new, message = BROKEN[case]
    assert EPUCK.count(old) >= 1
    path = tmp_path / "robot.xml"
    path.write_text(EPUCK.replace(old, new, 1))
    loads = [lambda: build_world(EPUCK_LAB.with_overrides(robot=str(path)), 3)]
    if case != "green shell":          # a colour is judged against teams: at world assembly
        loads.append(lambda: load_robot(str(path)))
    for load in loads:
        with pytest.raises(UserError) as err:
            load()
        text = str(err.value)
        assert "\n" not in text
        assert f"robot file {path}: " in text and message in text, text
    if case != "green shell":          # the scenario checks its robot when it is made
        with pytest.raises(UserError, match="robot.model: robot file"):
            EPUCK_LAB.with_overrides(robot=str(path))


def test_an_unknown_robot_is_refused_with_the_choices():
    with pytest.raises(UserError, match="robot.model: unknown robot 'rover'; choose one of "
                                        ".*epuck"):
        EPUCK_LAB.with_overrides(robot="rover")


@pytest.mark.parametrize("rgb", [(0.1, 0.8, 0.1), (0.9, 0.9, 0.1), (0.5, 0.5, 0.55),
                                 (0.15, 0.05, 0.05), (0.55, 0.7, 0.55), (0.2, 0.3, 0.9)])
def test_the_colour_rule_is_the_trackers(rgb):
    """A marker-sized patch of `rgb` is tracked as marker k exactly when the robot check's rule
    says k: the check refuses what the tracker would see, and nothing else."""
    world = build_world(SCENARIOS["lab"], 3)
    data = mujoco.MjData(world.model)
    mujoco.mj_forward(world.model, data)
    tracker = Tracker.for_world(world, data)
    frame = np.full((570, 750, 3), 180, np.uint8)
    frame[270:300, 360:390] = np.round(np.array(rgb) * 255).astype(np.uint8)   # 30 x 30 px
    seen = tracker.track(frame).detected
    expected = taken_for_marker(rgb, marker_colours(3))
    assert list(np.flatnonzero(seen)) == ([] if expected is None else [expected])


def test_the_epuck_drives_straight_at_its_top_speed_and_turns_on_the_spot():
    world = build_world(EPUCK_LAB, 2)
    sim = ChainSim(world)
    half = np.array(EPUCK_LAB.arena) / 2
    start = np.array([[-half[0] + 0.2, 0.0, 0.0], [half[0] - 0.1, half[1] - 0.1, 0.0]])
    dt, top = sim.model.opt.timestep, world.max_wheel_speed
    assert world.top_speed == pytest.approx(2 * np.pi * 0.0205, rel=1e-4)     # 0.129 m/s
    assert world.track == pytest.approx(0.053) and world.footprint_radius == pytest.approx(0.035)
    sim.reset(np.random.default_rng(0), start=start)
    traj = drive(sim, top, top, 4.0)
    v = np.mean(np.diff(traj[-400:, 0])) / dt
    assert v == pytest.approx(0.129, rel=0.02)
    assert np.max(np.abs(traj[:, 1])) < 0.002 and np.max(np.abs(wrap_angle(traj[:, 2]))) < 0.01
    sim.reset(np.random.default_rng(0), start=start)
    traj = drive(sim, -top, top, 4.0)
    omega = np.mean(wrap_angle(np.diff(traj[-400:, 2]))) / dt
    assert omega == pytest.approx(2 * world.top_speed / world.track, rel=0.02)  # 4.86 rad/s
    assert np.max(np.linalg.norm(traj[:, :2] - start[0, :2], axis=1)) < 0.002


@pytest.mark.slow
def test_an_epuck_chain_soaks_without_a_fault():
    runs = soak(soak_tasks(EPUCK_LAB, 5, 10, 60.0, first_seed=7000), workers=2)
    row = summary(runs, workers=2)
    assert [r.reason for r in runs if r.fault] == []
    assert row["runs"] == 10 and row["warnings"] == 0
    assert row["max_lift_mm"] < 3.0 and row["max_tilt_deg"] < 15.0

