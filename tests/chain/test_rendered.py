"""The robot contract judged as rendered (`chain.rendered`): a part whose authored colour passes
but whose lit colour the tracker takes for a marker is refused in one line; the shipped robots
pass; and the per-pixel rule is the tracker's own."""

import dataclasses
from pathlib import Path

import cv2
import numpy as np
import pytest
from clitools import cli_inprocess

from macrostate_mj.chain.markers import marker_colours, marker_of_pixels, taken_for_marker
from macrostate_mj.chain.rendered import check_rendered_colours
from macrostate_mj.chain.robot import load_robot
from macrostate_mj.chain.scenarios import SCENARIOS, get_scenario
from macrostate_mj.core.errors import UserError
from macrostate_mj.vision.camera import PinholeCamera
from macrostate_mj.vision.tracker import Tracker

# The GRITSBot with its shell dark blue (rgba 0.08 0.1 0.18): value 46/255 as authored, under
# the 50 the tracker needs, so the authored-colour contract passes it.
DARK_BLUE = Path(__file__).parent / "robots" / "dark_blue" / "robot.xml"
EPUCK_LAB = Path(__file__).parents[2] / "examples" / "epuck_lab.toml"


def hsv_of(rgb: np.ndarray) -> np.ndarray:
    return cv2.cvtColor(rgb.reshape(-1, 1, 3), cv2.COLOR_RGB2HSV_FULL).reshape(-1, 3)


@pytest.mark.parametrize("n", [2, 3, 5, 10, 17])
def test_the_pixel_rule_is_the_authored_colour_rule_on_8_bit_colours(n):
    """Up to the hue's rounding: `taken_for_marker` rounds colorsys's hue, OpenCV's integer
    conversion sometimes lands one level off, so colours on a tolerance's edge (a few in 3000)
    may differ."""
    rgb = np.random.default_rng(n).integers(0, 256, (3000, 3), dtype=np.uint8)
    colours = marker_colours(n)
    expected = np.array([-1 if (k := taken_for_marker(c / 255, colours)) is None else k
                         for c in rgb])
    assert (marker_of_pixels(hsv_of(rgb), colours) != expected).sum() <= 10


def test_the_pixel_rule_is_the_trackers():
    """A frame of one colour: the tracker finds marker k in it exactly when the rule says k."""
    camera = PinholeCamera(48, 48, 48.0, np.array([0.0, 0.0, 1.0]), np.diag([1.0, -1.0, -1.0]))
    colours = marker_colours(6)
    tracker = Tracker(camera, colours, 0.0, (8 / 48) ** 2)
    rng = np.random.default_rng(7)
    rgb = np.vstack([rng.integers(0, 256, (150, 3)), (255 * colours).round(),
                     [[50, 0, 0], [49, 0, 0], [255, 165, 165], [255, 166, 166]]]).astype(np.uint8)
    rule = marker_of_pixels(hsv_of(rgb), colours)
    for colour, k in zip(rgb, rule, strict=True):
        found = tracker.track(np.broadcast_to(colour, (48, 48, 3)).copy()).detected
        assert found.tolist() == [i == k for i in range(len(colours))], (colour, k)


def test_a_dark_part_that_renders_as_a_marker_colour_is_refused_in_one_line():
    load_robot(str(DARK_BLUE), largest_team=10)         # its authored colour passes
    cfg = SCENARIOS["robotarium"].with_overrides(robot=str(DARK_BLUE))
    with pytest.raises(UserError) as err:
        check_rendered_colours(cfg, 10)
    msg = str(err.value)
    assert "\n" not in msg and str(DARK_BLUE) in msg and "geom 'shell' renders at HSV" in msg
    assert "of a team of 10" in msg and "colour it darker or greyer" in msg


def test_the_refusal_reaches_scenario_check_as_exit_2(tmp_path, capsys):
    path = tmp_path / "dark.toml"
    path.write_text(f'extends = "robotarium"\nname = "dark"\n[robot]\nmodel = "{DARK_BLUE}"\n')
    code, out, err = cli_inprocess(capsys, "scenario", "check", str(path))
    assert code == 2 and len(err.strip().splitlines()) == 1 and "geom 'shell'" in err, err


@pytest.mark.parametrize("scenario", [*sorted(SCENARIOS), str(EPUCK_LAB)])
def test_the_shipped_robots_pass_as_rendered_in_their_scenarios(scenario):
    """Every colour team the scenario allows passes, judged on renders that do hold the robots'
    parts and markers (not a vacuous pass)."""
    from macrostate_mj.chain.rendered import _light_scales, rendered_parts
    from macrostate_mj.chain.robot import robot_file

    cfg = get_scenario(scenario)
    assert [check_rendered_colours(cfg, n) for n in range(2, 11)] == [None] * 9
    path = robot_file(cfg.robot)
    seen = rendered_parts(str(path), path.stat().st_mtime_ns, tuple(cfg.arena), cfg.camera,
                          cfg.look, _light_scales(cfg.imaging), cfg.imaging.light_tilt_deg)
    assert seen.parts and all(len(h) for h in seen.hsv) and (seen.marker_px > 0).all()


def test_the_check_leaves_an_open_overhead_renderer_as_it_was():
    """World building may call it while a run's renderer is open: its own GL context comes and
    goes, the run's frames stay bit for bit."""
    from macrostate_mj.chain.sim import ChainSim
    from macrostate_mj.chain.world import build_world
    from macrostate_mj.vision.camera import OverheadRenderer

    webots = SCENARIOS["webots"]                # a look no other test rendered: a cold check
    cfg = webots.with_overrides(look=dataclasses.replace(webots.look, light_diffuse=0.5))
    sim = ChainSim(build_world(cfg, 3))
    sim.reset(np.random.default_rng(0))
    with OverheadRenderer(sim.world.model) as renderer:
        before = renderer.render(sim.data).copy()
        check_rendered_colours(cfg, 3)
        assert np.array_equal(renderer.render(sim.data), before)
