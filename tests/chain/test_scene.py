"""The generated arena scene: the same model as the hand-written XMLs it replaced, the arena said
once (walls and camera follow from it), and a camera that cannot see the arena refused."""

import dataclasses
import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

from macrostate_mj.chain import world as world_module
from macrostate_mj.chain.scenarios import SCENARIOS, get_scenario
from macrostate_mj.chain.scene import Camera, Look, Physics, Walls, build_scene, check_camera
from macrostate_mj.chain.world import build_world
from macrostate_mj.core.errors import UserError

GOLDEN = Path(__file__).parent / "golden"


def saved(model: mujoco.MjModel) -> bytes:
    """The whole compiled model (options, visual, names and every array), as MuJoCo saves it."""
    buf = np.zeros(mujoco.mj_sizeModel(model), np.uint8)
    mujoco.mj_saveModel(model, None, buf)
    return buf.tobytes()


def scene_of(cfg) -> mujoco.MjSpec:
    return build_scene(cfg.name, cfg.arena, cfg.walls, cfg.camera, cfg.look, cfg.physics)


@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_generated_world_is_byte_identical_to_the_hand_written_scene(name, monkeypatch):
    generated = saved(build_world(SCENARIOS[name], 4).model)
    golden = GOLDEN / f"scene_{name}.xml"
    monkeypatch.setattr(world_module, "build_scene",
                        lambda *_: mujoco.MjSpec.from_file(str(golden)))
    assert generated == saved(build_world(SCENARIOS[name], 4).model)


@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_walls_and_camera_follow_from_the_arena(name):
    cfg = SCENARIOS[name]
    model = scene_of(cfg).compile()
    hx, hy = np.array(cfg.arena) / 2
    assert np.allclose(model.geom("floor").size[:2], [hx, hy])
    inner = {"east": model.geom("wall_east").pos[0] - model.geom("wall_east").size[0],
             "west": -model.geom("wall_west").pos[0] - model.geom("wall_west").size[0],
             "north": model.geom("wall_north").pos[1] - model.geom("wall_north").size[1],
             "south": -model.geom("wall_south").pos[1] - model.geom("wall_south").size[1]}
    assert np.allclose(list(inner.values()), [hx, hx, hy, hy])    # walls on the floor's edges
    for side in ("east", "west", "north", "south"):
        geom = model.geom(f"wall_{side}")
        assert geom.size[2] * 2 == pytest.approx(cfg.walls.height) and geom.pos[2] == geom.size[2]
    cam = model.camera("overhead")
    assert tuple(model.cam_resolution[cam.id]) == cfg.camera.resolution
    assert (model.vis.global_.offwidth, model.vis.global_.offheight) == cfg.camera.resolution
    assert model.opt.timestep == cfg.physics.timestep


def test_unset_fovy_frames_the_arena_on_its_limiting_axis():
    wide = Camera(height=2.0, resolution=(800, 400))     # 2:1 image, 2 x 1.6 m floor: y limits
    assert wide.fovy_for((2.0, 1.6)) == pytest.approx(2 * math.degrees(math.atan(0.8 / 2.0)))
    tall = Camera(height=2.0, resolution=(400, 400))     # square image: x limits
    assert tall.fovy_for((2.0, 1.6)) == pytest.approx(2 * math.degrees(math.atan(1.0 / 2.0)))
    for cam in (wide, tall):
        check_camera("test", (2.0, 1.6), cam)            # exactly framed: every corner seen
    cfg = get_scenario("lab")
    framed = dataclasses.replace(cfg.camera, fovy=None)
    assert framed.fovy_for(cfg.arena) == pytest.approx(cfg.camera.fovy, abs=0.01)


def test_a_camera_that_misses_a_corner_is_refused_in_one_line():
    cfg = get_scenario("lab")
    with pytest.raises(UserError) as err:
        cfg.with_overrides(camera=Camera(height=2.0, resolution=(750, 570), fovy=41.61))
    msg = str(err.value)
    assert "\n" not in msg and "north-east corner (1.25, 0.95) m" in msg and "px outside" in msg
    with pytest.raises(UserError, match="corner"):
        build_scene("x", (2.0, 2.0), Walls(), Camera(1.0, (100, 100), fovy=30.0), Look(),
                    Physics(0.005))


def test_an_open_floor_has_no_walls_and_an_unknown_integrator_is_named():
    cfg = get_scenario("webots")
    model = build_world(cfg.with_overrides(walls=None), 3).model
    names = {model.geom(i).name for i in range(model.ngeom)}
    assert "floor" in names and not any(n.startswith("wall_") for n in names)
    with pytest.raises(UserError, match="'rk5'.*implicitfast"):
        build_scene("x", cfg.arena, None, cfg.camera, cfg.look, Physics(0.005, integrator="rk5"))
