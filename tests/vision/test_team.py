"""`vision.team`: the team a recording's frames show, judged before `track` tracks them. Synthetic
frames (marker-sized discs of the team colours on a grey floor), so each case costs
milliseconds; the recorded round trips are in tests/app/test_track_footage.py."""

import cv2
import mujoco
import numpy as np
import pytest

from macrostate_mj.chain.markers import marker_colours
from macrostate_mj.chain.scenarios import get_scenario
from macrostate_mj.chain.world import build_world
from macrostate_mj.core.errors import UserError
from macrostate_mj.vision.camera import PinholeCamera
from macrostate_mj.vision.team import _ranges, check_team_shown, claims, colour_blobs, fits


def _world(n):
    world = build_world(get_scenario("lab"), n)
    data = mujoco.MjData(world.model)
    mujoco.mj_forward(world.model, data)
    return world, data


def _area_px(world, data):
    cam = PinholeCamera.from_model(world.model, data)
    return world.marker_area * (cam.focal / (cam.position[2] - world.marker_height)) ** 2


def _frames(world, data, shown, count=6, extra=()):
    """`count` frames of the lab's size with a marker-sized disc of each colour of a team of
    `shown` (rendered value), moved a little each frame; `extra`: (rgb 0-255, radius px)."""
    w, h = world.scenario.camera.resolution
    r = int(round(np.sqrt(_area_px(world, data) / np.pi)))
    colours = (marker_colours(shown) * 255).round().astype(int)
    frames = []
    for k in range(count):
        img = np.full((h, w, 3), 120, np.uint8)
        for i, c in enumerate(colours):
            centre = (60 + (i % 5) * 120 + 3 * k, 120 + (i // 5) * 200)
            cv2.circle(img, centre, r, tuple(int(v) for v in c), -1)
        for j, (c, radius) in enumerate(extra):
            cv2.circle(img, (100 + 150 * j, h - 100), radius, c, -1)
        frames.append(img)
    return frames


@pytest.mark.parametrize("shown,robots", [(10, 8), (10, 9), (8, 10), (3, 4), (4, 3), (5, 10),
                                          (2, 3)])
def test_a_colour_team_the_frames_contradict_is_refused_naming_the_count(shown, robots):
    world, data = _world(robots)
    with pytest.raises(UserError) as err:
        check_team_shown(world, data, _frames(world, data, shown), "v.mp4")
    line = str(err.value)
    assert "\n" not in line and f"shows {shown} colour markers" in line, line
    assert f"--robots is {robots}" in line and f"give --robots {shown}" in line, line


@pytest.mark.parametrize("n", [2, 3, 5, 6, 8, 10])
def test_the_team_filmed_passes(n):
    world, data = _world(n)
    check_team_shown(world, data, _frames(world, data, n), "v.mp4")


def test_specks_and_large_colour_areas_are_not_markers():
    world, data = _world(4)
    area = _area_px(world, data)
    frames = _frames(world, data, 4, extra=[((255, 0, 0), 1), ((0, 200, 0), 2),
                                            ((0, 0, 255), int(np.sqrt(4 * area)))])
    check_team_shown(world, data, frames, "v.mp4")
    assert len(colour_blobs(frames[0], area)) == 4


def test_a_robot_out_of_most_frames_does_not_make_another_team():
    """A 10-robot team with F5 (hue 128) missing from most frames shows 9 blobs that a team of 9
    would claim, yet each is the team of 10's: tracked (the detected share says the rest)."""
    world, data = _world(10)
    frames = _frames(world, data, 10)
    hidden = (marker_colours(10)[5] * 255).round().astype(int)
    for img in frames[:4]:
        img[np.all(img == hidden, axis=2)] = 120
    check_team_shown(world, data, frames, "v.mp4")


def test_claims_and_fits_are_the_trackers_hue_rule():
    hues = np.array([0, 26, 51, 77, 103, 128, 154, 179, 205, 230])     # a team of 10
    assert fits(hues, 10) and not fits(hues, 8) and not fits(hues, 9)
    assert claims(np.array([64, 48]), 8).tolist() == [2, -1]   # 48: 16 from 32 and 64 (tol 14)
    assert claims(np.empty(0, int), 4).tolist() == []


def test_tag_ids_are_named_as_runs():
    assert _ranges([0, 1, 2, 5, 7, 8]) == "0-2, 5, 7-8"
    assert _ranges([3]) == "3"
