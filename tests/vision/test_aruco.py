"""Fiducial tag markers: the tag plates the world builder draws and the tag tracker's poses and
ids on rendered frames, against ground truth."""

import mujoco
import numpy as np
import pytest

from macrostate_mj.chain.scenarios import get_scenario
from macrostate_mj.chain.scene import Camera
from macrostate_mj.chain.sim import ChainSim
from macrostate_mj.chain.tags import ArucoMarkers
from macrostate_mj.chain.world import build_world
from macrostate_mj.core.angles import wrap_angle
from macrostate_mj.core.errors import UserError
from macrostate_mj.vision.aruco import ArucoTracker
from macrostate_mj.vision.camera import OverheadRenderer
from macrostate_mj.vision.trackers import tracker_for

HALL = "examples/tag_hall.toml"


@pytest.fixture(scope="module")
def hall():
    """Four tagged e-pucks after 3 s of driving under a bending lens, one clean frame (a
    smaller hall and frame than the example's, at about its 2 px/cm)."""
    cfg = get_scenario(HALL).with_overrides(
        arena=(2.0, 1.5), camera=Camera(4.0, (800, 600), None, (-0.1, 0.0, 0.0, 0.0)))
    sim = ChainSim(build_world(cfg, 4))
    sim.reset(np.random.default_rng(5))
    sim.run(3.0, hooks=[])
    with OverheadRenderer(sim.model, distortion=cfg.camera.distortion) as renderer:
        frame = renderer.render(sim.data)
    return sim, frame


def errors(det, truth):
    pos_mm = np.linalg.norm(det.poses[:, :2] - truth[:, :2], axis=1) * 1000
    return pos_mm, np.degrees(np.abs(wrap_angle(det.poses[:, 2] - truth[:, 2])))


def test_clean_frames_give_every_id_at_sub_millimetre_accuracy(hall):
    sim, frame = hall
    tracker = tracker_for(sim.world, sim.data)
    assert isinstance(tracker, ArucoTracker)
    det = tracker.track(frame)
    pos_mm, head_deg = errors(det, sim.poses)
    assert det.detected.all()
    assert pos_mm.max() < 1.5 and head_deg.max() < 2.0      # a pixel is 2.5 mm here


def test_windows_find_what_the_whole_frame_finds(hall):
    sim, frame = hall
    tracker = tracker_for(sim.world, sim.data)
    uv = tracker.camera.world_to_pixel(np.column_stack(
        [sim.poses[:, :2], np.full(4, sim.world.marker_height)]))
    half = int(tracker.marker_radius_px) + 4
    parts = [(int(u) - half, int(v) - half,
              frame[int(v) - half:int(v) + half, int(u) - half:int(u) + half]) for u, v in uv]
    whole, windows = tracker.track(frame), tracker.track_regions(parts)
    assert windows.detected.all()       # adaptive thresholds differ a little at window edges
    np.testing.assert_allclose(windows.poses[:, :2], whole.poses[:, :2], atol=2e-5)
    np.testing.assert_allclose(windows.poses[:, 2], whole.poses[:, 2], atol=2e-3)


def test_ids_outside_the_team_are_ignored(hall):
    sim, frame = hall
    full = tracker_for(sim.world, sim.data)
    two = ArucoTracker(full.camera, full.markers, 2, full.marker_height, full.marker_area)
    det = two.track(frame)
    assert det.poses.shape == (2, 3) and det.detected.all()
    np.testing.assert_array_equal(det.poses, full.track(frame).poses[:2])


def test_the_plate_is_a_square_tag_at_the_cards_height():
    colour, tag = (build_world(get_scenario(f), 3)
                   for f in ("examples/epuck_lab.toml", HALL))
    assert tag.marker_height == pytest.approx(colour.marker_height, abs=1e-9)
    assert tag.marker_area == pytest.approx(0.051**2)     # the card's length
    data = mujoco.MjData(tag.model)
    mujoco.mj_forward(tag.model, data)
    g = tag.model.geom("F1/marker").id
    np.testing.assert_allclose(data.geom_xpos[g][:2], data.xpos[tag.body[1]][:2], atol=1e-9)
    assert tag.model.geom_matid[g] >= 0 and np.all(tag.colours == 1.0)


def test_bad_dictionaries_and_too_large_teams_are_refused(tmp_path):
    path = tmp_path / "hall.toml"
    path.write_text('extends = "lab"\nname = "hall"\n[markers]\nkind = "aruco"\n'
                    'dictionary = "DICT_9X9_7"\n')
    with pytest.raises(UserError, match="DICT_9X9_7.*use one of .*DICT_4X4_50") as err:
        get_scenario(path)
    assert "\n" not in str(err.value)
    with pytest.raises(UserError, match="51 robots need 51 tag ids but DICT_4X4_50 has 50"):
        ArucoMarkers("DICT_4X4_50").check_team(51)
    ArucoMarkers("DICT_4X4_50").check_team(50)
