"""Obstacles: a schema that round-trips, bad ones named, static geoms robots stop at, waypoints
and start poses clear of them, a health fault inside one, and markers they hide missed."""

from pathlib import Path

import cv2
import mujoco
import numpy as np
import pytest

from macrostate_mj.chain.health import Fault
from macrostate_mj.chain.planners import CellWalk, PresetTwists
from macrostate_mj.chain.scenario_file import load_scenario, to_toml
from macrostate_mj.chain.scene import Obstacle, blocked
from macrostate_mj.chain.sim import ChainSim
from macrostate_mj.chain.world import build_world, marker_area, place_chain
from macrostate_mj.core.errors import UserError
from macrostate_mj.vision.camera import PinholeCamera
from macrostate_mj.vision.tracker import Tracker

SCENARIO = Path(__file__).with_name("obstacles.toml")


@pytest.fixture(scope="module")
def cfg():
    return load_scenario(SCENARIO)


def test_obstacles_round_trip_through_a_scenario_file(cfg, tmp_path):
    assert cfg.obstacles == (Obstacle("box", (-0.8, 0.4), (0.5, 0.3, 0.2)),
                             Obstacle("box", (0.9, -0.5), (0.4, 0.6)))
    text = to_toml(cfg)
    assert 'obstacles = [{shape = "box", pos = [-0.8, 0.4], size = [0.5, 0.3, 0.2]}' in text
    (tmp_path / "shown.toml").write_text(text)
    assert load_scenario(tmp_path / "shown.toml") == cfg
    assert load_scenario("lab").obstacles == ()


@pytest.mark.parametrize("obstacle,words", [
    ('{shape = "cone", pos = [0, 0], size = [0.2]}', ["shape", "box, cylinder", "'cone'"]),
    ('{shape = "box", pos = [0, 0], size = [0.2]}', ["[x, y] or [x, y, height]"]),
    ('{shape = "cylinder", pos = [0, 0], size = [0.2, 0.1, 0.1]}', ["[diameter]"]),
    ('{shape = "box", pos = [0, 0], size = [0.2, -0.1]}', ["positive"]),
    ('{shape = "cylinder", pos = [1.2, 0], size = [0.2]}', ["outside", "2.5 x 1.9"]),
    ('{shape = "box", pos = [0, 0]}', ["size"]),
    ('{shape = "box", pos = [0], size = [0.2, 0.2]}', ["pos", "2 values"]),
])
def test_a_bad_obstacle_is_refused_in_one_line_naming_it(tmp_path, obstacle, words):
    path = tmp_path / "bad.toml"
    path.write_text('extends = "lab"\n[arena]\nobstacles = [\n'
                    '  {shape = "box", pos = [0.5, 0.5], size = [0.2, 0.2]},\n'
                    f'  {obstacle},\n]\n')
    with pytest.raises(UserError) as err:
        load_scenario(path)
    message = str(err.value)
    assert "\n" not in message and "arena.obstacles[1]" in message and "bad.toml" in message
    for w in words:
        assert w in message, message


def test_no_obstacles_keep_a_scene_without_them(cfg):
    lab = build_world(load_scenario("lab"), 3).model
    assert all(not lab.geom(g).name.startswith("obstacle") for g in range(lab.ngeom))
    model = build_world(cfg, 3).model
    wall, box = model.geom("wall_east"), model.geom("obstacle_0")
    for attr in ("contype", "conaffinity", "priority", "friction"):
        assert np.array_equal(getattr(wall, attr), getattr(box, attr)), attr
    assert np.allclose(box.size, [0.25, 0.15, 0.1]) and np.allclose(box.pos, [-0.8, 0.4, 0.1])
    assert np.allclose(model.geom("obstacle_1").size, [0.2, 0.3, 0.05])     # default height


@pytest.mark.parametrize("spec", ["psi", CellWalk((12, 8))])
def test_waypoints_never_fall_within_the_margin_of_an_obstacle(cfg, spec):
    spec = cfg.planner if spec == "psi" else spec
    planner = spec.build(cfg.arena, cfg.wall_margin, cfg.reach_radius, cfg.obstacles)
    targets = []
    for seed in range(20):
        rng = np.random.default_rng(seed)
        start = place_chain(cfg, 8, rng)
        assert not blocked(cfg.obstacles, start[:, :2], cfg.wall_margin).any()
        planner.reset(start[0], rng)
        for k in range(100):
            targets.append(planner.target)
            planner.update(np.array([*planner.target, 0.0]), float(k), rng)  # reached
    targets = np.array(targets)
    assert not blocked(cfg.obstacles, targets, cfg.wall_margin).any()
    assert len(np.unique(targets.round(3), axis=0)) > 40        # it does roam


def test_a_preset_head_turns_away_from_an_obstacle(cfg):
    planner = PresetTwists().build(cfg.arena, cfg.wall_margin, cfg.reach_radius, cfg.obstacles)
    rng = np.random.default_rng(0)
    facing = np.array([-1.15, 0.4, 0.0])        # 0.1 m west of obstacle 0, facing it
    planner.reset(facing, rng)
    assert planner.twist[0] == 0.0 and planner.twist[1] != 0.0
    planner.update(np.array([-1.15, 0.4, np.pi]), 0.5, rng)     # facing away: drives on
    assert planner.twist == planner.presets[0]


def _sim(cfg, start):
    sim = ChainSim(build_world(cfg, 2))
    sim.reset(np.random.default_rng(0), start=np.array(start))
    return sim


def test_a_robot_driven_into_an_obstacle_stops_at_it(cfg):
    # The Head 0.3 m west of obstacle 0, both wheels at top speed toward it for 10 s.
    sim = _sim(cfg, [[-1.35, 0.4, 0.0], [-1.6, -1.0, 0.0]])
    w, m, d = sim.world, sim.model, sim.data
    d.ctrl[w.ctrl_left[0]] = d.ctrl[w.ctrl_right[0]] = w.max_wheel_speed
    box = m.geom("obstacle_0").id
    touched = False
    for _ in range(int(10 / m.opt.timestep)):
        mujoco.mj_step(m, d)
        touched |= any(box in (c.geom1, c.geom2) for c in d.contact[:d.ncon])
        assert sim.monitor.check(d) is None
    gap = cfg.obstacles[0].distance(sim.poses[:1, :2])[0][0]     # centre to the box's face
    assert touched and 0.03 < gap < w.footprint_radius + 0.003
    assert abs(sim.poses[0, 1] - 0.4) < 0.02                  # pressed on, not slid past


@pytest.mark.parametrize("ob", [Obstacle("box", (0.3, -0.2), (0.4, 0.2)),
                                Obstacle("cylinder", (0.1, 0.1), (0.3,))])
def test_the_health_checks_depth_agrees_with_the_signed_distance(ob):
    xy = np.random.default_rng(0).uniform(-1, 1, (20000, 2))
    dist, depth = ob.distance(xy)[0], ob.depth(xy)
    assert np.array_equal(depth > 0, dist < 0)
    assert np.allclose(depth[dist < 0], -dist[dist < 0])
    assert (-depth <= dist + 1e-12).all()          # a bound of the distance outside too
    for radius in (0.05, 0.3):       # `within` may err only on the side of looking closer
        near = dist < radius
        assert ob.within(xy[near], radius) and not ob.within(xy[-depth >= radius], radius)


def test_a_centre_inside_an_obstacle_is_a_health_fault(cfg):
    sim = _sim(cfg, [[-1.35, 0.4, 0.0], [-1.6, -1.0, 0.0]])
    assert sim.monitor.check(sim.data) is None
    sim.data.qpos[sim.world.qpos_adr[1]:sim.world.qpos_adr[1] + 2] = [0.9, -0.45]
    mujoco.mj_forward(sim.model, sim.data)
    fault = sim.monitor.check(sim.data)
    assert fault.fault == Fault.INTRUDE and fault.robot == "T"
    assert fault.value == pytest.approx(200.0, abs=1.0)       # 0.2 m in from the nearest face
    assert "inside an obstacle" in fault.describe()


def test_a_marker_an_obstacle_hides_from_the_camera_is_missed(cfg):
    """Two markers drawn in a frame; the one whose line of sight to the overhead camera passes
    over the 0.2 m box is missed, the other is tracked."""
    world = build_world(cfg, 2)
    data = mujoco.MjData(world.model)
    mujoco.mj_forward(world.model, data)
    camera = PinholeCamera.from_model(world.model, data)
    area = marker_area(world.spec, f"{world.names[0]}/marker")
    args = (camera, world.colours, world.marker_height, area)
    # West of the box (the camera is over the centre, east of it): seen over the box's top.
    hidden, seen = np.array([-1.1, 0.4]), np.array([1.5, 1.0])
    frame = np.full((camera.height, camera.width, 3), 180, np.uint8)
    side = np.sqrt(4 * area / np.sqrt(3))                      # an equilateral marker
    for xy, colour in zip((hidden, seen), world.colours, strict=True):
        tri = xy + side * np.array([[0.577, 0], [-0.289, 0.5], [-0.289, -0.5]])
        uv = camera.world_to_pixel(np.column_stack([tri, np.full(3, world.marker_height)]))
        cv2.fillPoly(frame, [np.round(uv).astype(np.int32)],
                     tuple(int(c) for c in np.round(np.asarray(colour) * 255)))
    plain = Tracker(*args).track(frame)
    assert plain.detected.all()
    assert np.allclose(plain.poses[:, :2], [hidden, seen], atol=0.01)
    det = Tracker(*args, occluders=cfg.obstacles).track(frame)
    assert det.detected.tolist() == [False, True] and np.isnan(det.poses[0]).all()
    assert np.array_equal(det.poses[1], plain.poses[1])
