"""Scenario files: built-ins are files, a user's file extends one, bad keys name the key."""

from pathlib import Path

import pytest

from macrostate_mj.chain.scenario_file import builtin_names, load_scenario, to_toml
from macrostate_mj.core.errors import UserError


def _write(tmp_path, text, name="mylab.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


@pytest.mark.parametrize("name", ["lab", "webots", "robotarium"])
def test_a_builtin_written_back_loads_as_itself(tmp_path, name):
    cfg = load_scenario(name)
    assert load_scenario(_write(tmp_path, to_toml(cfg))) == cfg
    assert name in builtin_names()


def test_a_file_extends_a_builtin_and_overrides_keys(tmp_path):
    path = _write(tmp_path, 'extends = "lab"\nname = "mylab"\n[arena]\nsize = [4.0, 3.0]\n'
                            '[camera]\nheight = 3.0\nresolution = [1280, 960]\nfovy = "auto"\n'
                            '[chain]\nspacing = 0.25\n')
    cfg, lab = load_scenario(path), load_scenario("lab")
    assert (cfg.name, cfg.arena, cfg.spacing) == ("mylab", (4.0, 3.0), 0.25)
    assert cfg.camera.fovy is None and cfg.camera.resolution == (1280, 960)   # framed
    assert (cfg.k_f, cfg.planner, cfg.physics) == (lab.k_f, lab.planner, lab.physics)
    child = _write(tmp_path, 'extends = "mylab.toml"\n[chain]\nk_f = 5.0\n', "child.toml")
    assert load_scenario(child).arena == (4.0, 3.0) and load_scenario(child).k_f == 5.0


@pytest.mark.parametrize("text,words", [
    ('extends = "lab"\n[arena]\nsizes = [1, 1]\n', ["arena.sizes", "mylab.toml"]),
    ('extends = "lab"\n[cam]\nheight = 1\n', ["unknown key 'cam'"]),
    ('extends = "lab"\n[chain]\nspacing = "far"\n', ["chain.spacing", "number"]),
    ('extends = "lab"\n[arena]\nsize = [4.0]\n', ["arena.size", "2 values"]),
    ('extends = "lab"\n[camera]\nheight = 0.5\nresolution = [640, 480]\nfovy = 30.0\n',
     ["does not see", "corner"]),
    ('extends = "lab"\n[physics]\ntimestep = 0.004\n', ["whole", "steps"]),
    ('extends = "nowhere"\n', ["unknown scenario 'nowhere'"]),
    ('extends = "mylab.toml"\n', ["loops"]),
    ('name = "x"\n', ["missing"]),
    ('extends = "lab"\n[planner]\nkind = "spiral"\n', ["planner.kind", "psi_grid"]),
    ('extends = "lab"\n[arena]\nwalls = "yes"\n', ["arena.walls"]),
    ('extends = "lab"\n[chain]\nk_f = nan\n', ["chain.k_f", "finite"]),
    ('extends = "lab"\n[chain]\nspacing = -0.2\n', ["mylab.toml", "chain.spacing", "positive"]),
    ('extends = "lab"\n[arena]\nsize = [-4.0, 3.0]\n', ["arena.size", "positive"]),
    ('extends = "lab"\n[chain]\nhead_speed = 1.0\n', ["chain.head_speed", "top speed"]),
    ('extends = "lab"\n[robot]\nmodel = "rover"\n', ["mylab.toml", "robot.model", "'rover'"]),
    ('extends = "lab"\n[robot]\nmodel = "mine/robot.xml"\n', ["robot.model", "mine/robot.xml"]),
    # an outsider's trial: each of these got past the loader and failed later, or not at all
    ('extends = "lab"\n[arena]\nmargin = 5.0\n', ["mylab.toml", "arena.margin", "no floor"]),
    ('extends = "lab"\nname = 5\n', ["mylab.toml", "name"]),
    ('extends = "lab"\n[planner]\ngrid = [0, 8]\n', ["planner.grid", "at least 1"]),
    ('extends = "lab"\n[physics]\nintegrator = "rk5"\n', ["mylab.toml", "physics.integrator"]),
    ('extends = "lab"\n[look]\nfloor_rgba = [2, 0, 0, 1]\n', ["look.floor_rgba", "[0, 1]"]),
    ('extends = "lab"\n[arena]\nobstacles = [{shape = "box", pos = [0.5, 0.5], '
     'size = [0.2, 0.2, 3.0]}]\n', ["arena.obstacles[0]", "camera"]),
])
def test_bad_files_are_one_line_naming_the_key(tmp_path, text, words):
    path = _write(tmp_path, text)
    with pytest.raises(UserError) as err:
        load_scenario(path)
    message = str(err.value)
    assert "\n" not in message and isinstance(err.value, ValueError)
    for w in words:
        assert w in message, message


def test_a_rule_of_another_kind_replaces_the_inherited_table(tmp_path):
    path = _write(tmp_path, 'extends = "lab"\n[planner]\nkind = "cell_walk"\ngrid = [6, 4]\n'
                            '[followers]\nkind = "two_neighbours"\n')
    cfg = load_scenario(path)
    assert type(cfg.planner).__name__ == "CellWalk" and cfg.planner.grid == (6, 4)
    assert type(cfg.followers).__name__ == "TwoNeighbours"
    twists = _write(tmp_path, 'extends = "lab"\n[planner]\nkind = "preset_twists"\n', "t.toml")
    assert type(load_scenario(twists).planner).__name__ == "PresetTwists"


def test_the_python_api_refuses_what_the_cli_does():
    from macrostate_mj.chain.scenarios import get_scenario
    from macrostate_mj.chain.world import build_world

    lab = get_scenario("lab")
    for bad, words in (({"k_f": float("nan")}, "k_f"), ({"spacing": -0.2}, "spacing"),
                       ({"arena": (0.0, 1.0)}, "arena"), ({"command_hz": 0.0}, "command rate")):
        with pytest.raises(ValueError, match=words):
            lab.with_overrides(**bad)
    with pytest.raises(ValueError, match=r"head_speed \(chain.head_speed .*top speed"):
        lab.with_overrides(head_speed=1.0)
    with pytest.raises(ValueError, match="at least 2"):
        build_world(lab, 1)


def test_a_relative_robot_path_is_relative_to_the_file_that_says_it(tmp_path):
    from macrostate_mj.chain.robot import ASSETS

    (tmp_path / "robots").mkdir()
    (tmp_path / "robots" / "bot.xml").write_text((ASSETS / "epuck" / "robot.xml").read_text())
    (tmp_path / "labs").mkdir()
    _write(tmp_path, 'extends = "../epuck_lab.toml"\n', "labs/child.toml")
    base = (Path(__file__).parents[2] / "examples" / "epuck_lab.toml").read_text()
    _write(tmp_path, base.replace('model = "epuck"', 'model = "robots/bot.xml"'),
           "epuck_lab.toml")
    cfg = load_scenario(tmp_path / "labs" / "child.toml")
    assert Path(cfg.robot) == tmp_path / "robots" / "bot.xml"


def test_an_arena_obstacles_fill_is_named_not_the_team_size():
    from macrostate_mj.chain.scene import Obstacle
    from macrostate_mj.chain.world import build_world

    lab = load_scenario("lab")
    full = lab.with_overrides(obstacles=(Obstacle("box", (0.0, 0.0), (2.4, 1.8)),))
    with pytest.raises(UserError, match="room for no chain .*arena.margin") as err:
        build_world(full, 3)
    assert err.value.param == "obstacles"


def test_what_an_outsider_tried_is_refused_from_python():
    """A camera so low that "framing" the arena needs a fisheye, a fractional team, a run of
    infinite or negative length: each a ValueError naming the value."""
    import math

    from macrostate_mj.chain.scenarios import get_scenario
    from macrostate_mj.chain.scene import Camera
    from macrostate_mj.chain.sim import ChainSim
    from macrostate_mj.chain.world import build_world

    lab = get_scenario("lab")
    with pytest.raises(ValueError, match="camera.height"):
        lab.with_overrides(camera=Camera(0.02, (750, 570)))
    with pytest.raises(ValueError, match="whole number"):
        build_world(lab, 2.5)
    sim = ChainSim(build_world(lab, 3))
    for bad in (math.inf, math.nan, -1.0):
        with pytest.raises(ValueError, match="seconds"):
            sim.run(bad, [])
    import numpy as np

    with pytest.raises(ValueError, match="no field bogus"):
        lab.with_overrides(bogus=1)
    for start in (np.zeros((2, 3)), np.full((3, 3), 9.0), np.full((3, 3), np.nan)):
        with pytest.raises(ValueError, match="start"):
            build_world(lab, 3, start=start)
    with pytest.raises(ValueError, match="k_t"):
        ChainSim(build_world(lab, 3), k_t=math.nan)
    with pytest.raises(ValueError, match="scenario_for resolves a built-in's name"):
        build_world("lab", 3)                     # resolved once where a call begins


def test_the_noise_table_sets_the_imaging_noise_beside_the_marker_jitter(tmp_path):
    """`[noise]` takes every `NoiseConfig` field as well as `marker_jitter`; the camera chain
    uses the scenario's own noise; a bad value or key is one line naming `noise.<key>`."""
    import numpy as np

    from macrostate_mj.chain.sim import ChainSim
    from macrostate_mj.chain.world import build_world
    from macrostate_mj.vision.camera_chain import CameraChain
    from macrostate_mj.vision.imaging import NoiseConfig

    path = _write(tmp_path, 'extends = "lab"\nname = "noisy"\n[noise]\nmarker_jitter = 0.001\n'
                            'head_jitter_scale = 0.7\nsensor_sigma = 5.0\ndrop_prob = 0.01\n'
                            'jpeg_quality = [60, 80]\n')
    cfg = load_scenario(path)
    assert cfg.marker_jitter == 0.001 and cfg.head_jitter_scale == 0.7
    assert cfg.imaging == NoiseConfig(sensor_sigma=5.0, drop_prob=0.01, jpeg_quality=(60, 80))
    assert load_scenario("lab").imaging == NoiseConfig()            # built-ins: the defaults
    assert load_scenario(_write(tmp_path, to_toml(cfg), "back.toml")) == cfg
    chain = CameraChain(ChainSim(build_world(cfg, 3)), rng=np.random.default_rng(0))
    assert chain.noise == cfg.imaging
    chain.close()
    for text, words in [("drop_prob = 2.0", ["noise.drop_prob", "probability"]),
                        ("sensor_sigma = -1.0", ["noise.sensor_sigma", "non-negative"]),
                        ("jpeg_quality = [90, 80]", ["noise.jpeg_quality", "range"]),
                        ("head_jitter_scale = -0.5", ["noise.head_jitter_scale",
                                                      "non-negative"]),
                        ("sensor_noise = 1.0", ["noise.sensor_noise", "sensor_sigma",
                                                "marker_jitter"])]:
        bad = _write(tmp_path, f'extends = "lab"\n[noise]\n{text}\n', "bad.toml")
        with pytest.raises(UserError) as err:
            load_scenario(bad)
        assert all(w in str(err.value) for w in words), str(err.value)
        assert "\n" not in str(err.value)
