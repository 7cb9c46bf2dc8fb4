"""The generated arena scene: the same model as the hand-written XMLs it replaced, the arena said
once (walls and camera follow from it), and a camera that cannot see the arena refused."""

import dataclasses
import math
from pathlib import Path

import mujoco
import numpy as np
import pytest
from clitools import cli_inprocess

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


def lensed(cfg, distortion):
    return cfg.with_overrides(camera=dataclasses.replace(cfg.camera, distortion=distortion))


@pytest.mark.parametrize("k1", [-0.2, -0.35])
def test_a_lens_that_bends_without_folding_passes(k1):
    """Accepted, and the arena's corners land inside the frame through the lens (a barrel lens
    pulls them in); the built-ins and the e-puck example still load."""
    cfg = lensed(get_scenario("lab"), (k1, 0.0, 0.0, 0.0))
    assert cfg.camera.distortion == (k1, 0.0, 0.0, 0.0)
    corners = cfg.camera.floor_pixels(cfg.arena, np.array([[1.25, 0.95], [-1.25, -0.95]]))
    w, h = cfg.camera.resolution
    assert (np.abs(corners) < [w / 2, h / 2]).all()
    assert {get_scenario(name).name for name in SCENARIOS} == set(SCENARIOS)
    epuck = get_scenario(str(Path(__file__).parents[2] / "examples" / "epuck_lab.toml"))
    assert epuck.camera.distortion[0] == -0.2


@pytest.mark.parametrize(("distortion", "fix"), [
    ((-2.0, 0.0, 0.0, 0.0), "set k2 = 1.801 (or more), which makes it one-to-one over the "
                            "image, or reduce |k1|"),
    ((0.0, -0.63, 0.0, 0.0), "set k2 = -0.539 (or more), which makes it one-to-one over the "
                             "image and moves the arena's image by 5.3 px at most"),
    ((0.0, 0.0, 0.3, 0.0), "set k2 = 0.222 (or more), which makes it one-to-one over the "
                           "image, with camera.fovy = 61.8 to frame the arena, or reduce |p1|"),
    ((0.0, 0.0, 3.0, 0.0), "reduce |p1|"),             # no k2 unfolds a tangential fold
])
def test_a_lens_that_folds_the_image_is_refused_in_one_line(distortion, fix):
    with pytest.raises(UserError) as err:
        lensed(get_scenario("lab"), distortion)
    msg = str(err.value)
    assert "\n" not in msg and "folds the image over itself" in msg and msg.endswith(fix)
    assert f"[{', '.join(f'{c:g}' for c in distortion)}]" in msg


@pytest.mark.parametrize("distortion", [(-2.0, 0.0, 0.0, 0.0), (0.0, -0.63, 0.0, 0.0),
                                        (0.0, 0.0, 0.3, 0.0), (-0.25, 0.0, 0.0, 0.0)])
def test_the_k2_a_folding_lens_is_told_to_take_unfolds_it(distortion):
    """The lens with the k2 (and fovy) its refusal names passes; 0.01 less still folds (the
    k2 named is rounded up to 0.001)."""
    cfg = get_scenario(str(Path(__file__).parents[2] / "examples" / "epuck_lab.toml")
                       if distortion[0] == -0.25 else "lab")
    with pytest.raises(UserError) as err:
        lensed(cfg, distortion)
    msg = str(err.value)
    k2 = float(msg.split("set k2 = ")[1].split()[0])
    fovy = float(msg.split("camera.fovy = ")[1].split()[0]) if "camera.fovy" in msg else None
    unfolded = (distortion[0], k2, *distortion[2:])
    camera = dataclasses.replace(cfg.camera, distortion=unfolded, fovy=fovy or cfg.camera.fovy)
    check_camera(cfg.name, cfg.arena, camera)
    with pytest.raises(UserError, match="folds the image over itself"):
        check_camera(cfg.name, cfg.arena, dataclasses.replace(
            camera, distortion=(distortion[0], k2 - 0.01, *distortion[2:])))


def test_a_lens_folding_only_outside_the_arenas_image_is_refused_naming_k2(tmp_path, capsys):
    """The e-puck lab's 4 x 3 m arena reaches 661 px from the centre of its 1280 x 960 image
    through a k1 = -0.25 barrel lens, which folds at 739 px, short of the 800 px corners: the
    refusal says where, and the k2 that unfolds it; scenario check and simulate alike."""
    path = tmp_path / "barrel.toml"
    path.write_text(f'extends = "{Path(__file__).parents[2] / "examples" / "epuck_lab.toml"}"\n'
                    'name = "barrel"\n[camera]\ndistortion = [-0.25, 0, 0, 0]\n')
    line = ("barrel: the overhead camera's lens [k1, k2, p1, p2] = [-0.25, 0, 0, 0] folds the "
            "image over itself 739 px from its centre, outside the arena's image (661 px out) "
            "but inside the 1280 x 960 image (corners 800 px out); set k2 = 0.02 (or more), "
            "which makes it one-to-one over the image and moves the arena's image by 6.2 px at "
            "most, or reduce |k1|")
    out = tmp_path / "run"
    for args in (["scenario", "check", str(path)],
                 ["simulate", "--scenario", str(path), "--robots", "3", "--seconds", "1",
                  "--track", "--out", str(out)]):
        code, _, err = cli_inprocess(capsys, *args)
        assert code == 2 and len(err.strip().splitlines()) == 1 and line in err, err
    assert not out.exists()


def test_the_k2_fold_lies_near_the_corners_only():
    """[0, -0.63, 0, 0] is one-to-one out to 450 px of the lab image's 471 px corners: the
    arena's own corners still land inside the frame, so only the fold check refuses it."""
    cam = dataclasses.replace(get_scenario("lab").camera, distortion=(0.0, -0.63, 0.0, 0.0))
    arena = get_scenario("lab").arena
    corners = cam.floor_pixels(arena, [[1.25, 0.95], [-1.25, -0.95]])
    assert (np.abs(corners) < [375, 285]).all()
    with pytest.raises(UserError, match="folds the image over itself 4[45]\\d px"):
        check_camera("lab", arena, cam)


def test_a_pincushion_lens_that_pushes_the_arena_out_of_frame_is_refused():
    with pytest.raises(UserError) as err:
        lensed(get_scenario("lab"), (3.0, 0.0, 0.0, 0.0))
    msg = str(err.value)
    assert "\n" not in msg and "north-east corner (1.25, 0.95) m, 443.8 px outside" in msg
    assert "bends it out of a frame fitted for an ideal lens: set camera.fovy = 79.4" in msg
    with pytest.raises(UserError, match="px outside") as err:
        lensed(get_scenario("lab"), (0.05, 0.0, 0.0, 0.0))
    wide = float(str(err.value).split("set camera.fovy = ")[1].split()[0])
    cfg = get_scenario("lab")                        # the fovy it names frames the arena
    camera = dataclasses.replace(cfg.camera, fovy=wide, distortion=(0.05, 0.0, 0.0, 0.0))
    ok = cfg.with_overrides(camera=camera)
    assert ok.camera.fovy == wide


def test_an_edge_bent_out_between_corners_inside_is_named():
    """A camera framing the arena exactly, with a lens whose radial gain peaks between the
    arena's edge middles and its corners: the corners come inward, the edges bulge out."""
    cam = Camera(height=2.0, resolution=(400, 240), fovy=2 * math.degrees(math.atan(0.3)))
    check_camera("x", (2.0, 1.2), cam)
    bent = dataclasses.replace(cam, distortion=(0.3, -1.0, 0.0, 0.0))
    assert (np.abs(bent.floor_pixels((2.0, 1.2), [[1.0, 0.6]])) < [200, 120]).all()
    with pytest.raises(UserError, match=r"arena's north edge \(0\.5, 0\.6\) m, 2\.7 px outside"):
        check_camera("x", (2.0, 1.2), bent)


def test_a_folding_lens_is_refused_by_check_and_simulate_with_exit_2_and_nothing_written(
        tmp_path, capsys):
    path = tmp_path / "folded.toml"
    path.write_text('extends = "lab"\nname = "folded"\n[camera]\ndistortion = [-2.0, 0, 0, 0]\n')
    out = tmp_path / "run"
    for args in (["scenario", "check", str(path)],
                 ["simulate", "--scenario", str(path), "--robots", "3", "--seconds", "1",
                  "--out", str(out)]):
        code, _, err = cli_inprocess(capsys, *args)
        assert code == 2 and len(err.strip().splitlines()) == 1, err
        assert "folds the image over itself" in err and "set k2 = 1.801" in err
        assert "or reduce |k1|" in err
    assert not out.exists()
    with pytest.raises(UserError, match="folds"):
        build_world(get_scenario(path), 3)        # the Python API refuses it too


def test_the_local_scale_is_the_pinhole_one_without_a_lens_and_smaller_at_barrel_corners():
    cfg = get_scenario("lab")
    centre_and_corner = [[0.0, 0.0], [1.25, 0.95]]
    ideal = cfg.camera.px_per_m_at(cfg.arena, centre_and_corner)
    assert ideal == pytest.approx(cfg.camera.focal_for(cfg.arena) / cfg.camera.height)
    barrel = dataclasses.replace(cfg.camera, distortion=(-0.2, 0.0, 0.0, 0.0))
    bent = barrel.px_per_m_at(cfg.arena, centre_and_corner)
    assert bent[0] == pytest.approx(ideal[0]) and bent[1] < 0.9 * ideal[1]


def test_scenario_check_prints_the_lens_the_corner_scale_the_markers_and_obstacles(capsys):
    path = Path(__file__).parents[2] / "examples" / "epuck_lab.toml"
    code, out, err = cli_inprocess(capsys, "scenario", "check", str(path))
    assert code == 0, err
    lines = {line.split()[0]: line for line in out.splitlines()}
    assert "3.20 px/cm at the centre, 1.87 px/cm at the north-east corner" in lines["camera"]
    assert lines["lens"].endswith("[k1, k2, p1, p2] = [-0.2, 0, 0, 0]")
    assert lines["markers"].startswith("markers    colour") and "taken for no marker" in out
    assert lines["obstacles"] == ("obstacles  2: box 0.4 x 0.3 x 0.15 m at (0.9, 0.6); "
                                  "box 0.3 x 0.5 x 0.15 m at (-1, -0.7)")
    code, out, _ = cli_inprocess(capsys, "scenario", "check", "lab")
    assert "lens       ideal (pinhole)" in out and "obstacles  none" in out
    assert "3.00 px/cm at the centre, 3.00 px/cm" in out

