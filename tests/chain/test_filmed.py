"""What a tracked run checks up front about what its camera films (`chain.filmed`), and `scenario
check` with the same rule: a floor or obstacle in a marker's colour, tags too narrow in pixels;
and `scenario check` printing the `[tracking]` limits and the tags' cell widths."""

import dataclasses
from pathlib import Path

import pytest
from clitools import assert_clean_error, cli, cli_inprocess

from macrostate_mj.chain.filmed import MIN_TAG_CELL_PX, check_filmed, check_tag_cells
from macrostate_mj.chain.rendered import _light_scales, rendered_scene
from macrostate_mj.chain.scenarios import SCENARIOS, get_scenario
from macrostate_mj.core.errors import UserError

EXAMPLES = Path(__file__).parents[2] / "examples"
HALL = EXAMPLES / "tag_hall.toml"


def scenario_file(tmp_path: Path, text: str, name: str = "lab_x") -> Path:
    path = tmp_path / f"{name}.toml"
    path.write_text(f'name = "{name}"\n{text}')
    return path


def test_a_green_floor_is_refused_by_scenario_check_and_a_tracked_run_alike(tmp_path):
    """The lab's floor in pale green passes for marker 2 of a team of 3 (it passed `scenario
    check` before and the run then failed, 129 mm off, blaming a robot's colour): both refuse it
    with the same line, exit 2, nothing written; an untracked run is not refused."""
    path = scenario_file(tmp_path, 'extends = "lab"\n[look]\nfloor_rgba = [0.3, 0.6, 0.3, 1]\n')
    out = tmp_path / "run"
    check = cli("scenario", "check", str(path))
    run = cli("simulate", "--scenario", str(path), "--robots", "3", "--seconds", "1", "--track",
              "--out", str(out))
    for res in (check, run):
        assert_clean_error(res, "lab_x: geom 'floor' (look.floor_rgba = [0.3, 0.6, 0.3, 1]) "
                           "renders at HSV 85 127 191", "marker 2 of a team of 3",
                           "colour it grey, e.g. look.floor_rgba = [0.48, 0.48, 0.48, 1]")
    assert check.stderr == run.stderr and not out.exists()
    fixed = get_scenario(path).with_overrides(look=dataclasses.replace(
        get_scenario(path).look, floor_rgba=(0.48, 0.48, 0.48, 1.0)))
    for n in range(2, 11):
        check_filmed(fixed, n)                  # the grey it names passes every team


def test_an_obstacle_in_a_marker_colour_is_refused_naming_it(tmp_path, capsys):
    """Obstacles wear the walls' colour (`look.wall_rgba`): an orange box on an open floor
    renders, under the brightest light the imaging noise draws, as marker 2 of a team of 6."""
    path = scenario_file(tmp_path, 'extends = "lab"\n[arena]\nwalls = false\nobstacles = [{shape '
                         '= "box", pos = [0.5, 0.3], size = [0.3, 0.2]}]\n[look]\nwall_rgba = '
                         '[0.9, 0.5, 0.1, 1]\n')
    code, _, err = cli_inprocess(capsys, "scenario", "check", str(path))
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert "geom 'obstacle_0' (look.wall_rgba = [0.9, 0.5, 0.1, 1])" in err
    assert "marker 2 of a team of 6" in err and "look.wall_rgba = [0.57, 0.57, 0.57, 1]" in err
    cfg = get_scenario(path)
    check_filmed(cfg, 5)                        # a team whose hues it misses runs
    with pytest.raises(UserError, match="obstacle_0"):
        check_filmed(cfg, 6)


@pytest.mark.parametrize("scenario", [*sorted(SCENARIOS), str(EXAMPLES / "epuck_lab.toml")])
def test_the_shipped_scenes_pass_judged_on_renders_that_hold_their_surfaces(scenario):
    """Their cameras frame the arena, so the walls outside it are out of view (the lens shows
    nothing the pinhole render lacks); the floor and every obstacle are judged."""
    cfg = get_scenario(scenario)
    seen = rendered_scene(tuple(cfg.arena), cfg.walls, cfg.obstacles, cfg.camera, cfg.look,
                          _light_scales(cfg.imaging), cfg.imaging.light_tilt_deg)
    expected = {"floor", *(f"obstacle_{i}" for i in range(len(cfg.obstacles)))}
    assert set(seen.geoms) == expected and all(c.sum() > 0 for c in seen.count)
    for n in range(2, 11):
        check_filmed(cfg, n)


def raised(tmp_path: Path, height: float) -> Path:
    """The tag hall with its camera raised at the example's fovy: smaller tags in the image."""
    return scenario_file(tmp_path, f'extends = "{HALL}"\n[camera]\nheight = {height}\n'
                         'fovy = 53.13\n', name="hall_high")


def test_tags_too_narrow_for_the_detector_are_refused_naming_the_width_and_the_fixes(tmp_path):
    """5 m up, the hall's cells are 2.78 px (the run loses up to 12 % of a robot's rows there):
    `scenario check` and `simulate --track` refuse with the width, the detector's need and the
    fixes with their figures; each fix named passes."""
    path = raised(tmp_path, 5.0)
    out = tmp_path / "run"
    check = cli("scenario", "check", str(path))
    run = cli("simulate", "--scenario", str(path), "--robots", "3", "--seconds", "1", "--track",
              "--out", str(out))
    for res in (check, run):
        assert_clean_error(res, "hall_high: the tags' cells are filmed 2.78 px wide at the "
                           "arena's north-east corner", f"under the {MIN_TAG_CELL_PX:g} px",
                           "raise camera.resolution to 4417 x 2485",
                           "lower the camera to 4.35 m (its fovy kept)",
                           "a marker card at least 5.9 cm long (its geom 'marker'")
    assert check.stderr == run.stderr and not out.exists()
    cfg = get_scenario(path)
    for camera in (dataclasses.replace(cfg.camera, resolution=(4417, 2485)),
                   dataclasses.replace(cfg.camera, height=4.35)):
        assert check_tag_cells(cfg.with_overrides(camera=camera)).worst >= MIN_TAG_CELL_PX


def test_a_lens_that_squeezes_the_corners_is_judged_there():
    """A barrel lens films the corner cells narrower than the centre's; the worst corner is
    the one judged, and a fovy that follows the arena offers no lower camera."""
    cfg = get_scenario(HALL)
    barrel = cfg.with_overrides(camera=dataclasses.replace(cfg.camera,
                                                           distortion=(-0.1, 0.0, 0.0, 0.0)))
    cells = check_tag_cells(cfg)
    with pytest.raises(UserError) as err:
        check_tag_cells(barrel)
    msg = str(err.value)
    assert "lower the camera" not in msg and "at the image's centre" in msg
    centre, worst = (float(msg.split(key)[0].split()[-1].strip("(")) for key in
                     (" px at the image's centre", " px wide at the arena's"))
    assert centre == pytest.approx(cells.centre, abs=0.01) and worst < MIN_TAG_CELL_PX


def test_scenario_check_prints_the_limits_and_the_tag_cells(tmp_path, capsys):
    code, out, err = cli_inprocess(capsys, "scenario", "check", str(HALL))
    assert code == 0, err
    lines = {line.split()[0]: line for line in out.splitlines()}
    assert lines["markers"].endswith("tag cells 3.49 px at the centre, 3.49 px at the "
                                     "north-east corner (the detector needs 3.2 px)")
    assert lines["tracking"] == ("tracking   limits: min_detected 90%, max_hidden 10%, "
                                 "max_median_mm 3 mm, max_p99_mm 20 mm, max_heading_off30 5%, "
                                 "max_heading_flips 1%, max_identity_errors 1%")
    path = scenario_file(tmp_path, 'extends = "lab"\n[tracking]\nmax_median_mm = 5\n'
                         "min_detected = 0.95\n")
    code, out, err = cli_inprocess(capsys, "scenario", "check", str(path))
    assert code == 0, err
    assert "limits: min_detected 95%, max_hidden 10%, max_median_mm 5 mm" in out
    assert "floor, walls and robot parts as rendered taken for no marker (teams of 2-10)" in out


def test_the_scene_render_is_cached_and_cheap_after_the_first():
    """A tracked run calls the check at its start: after the first call for a scene, a team
    size is judged in milliseconds."""
    import time

    cfg = get_scenario("webots")
    check_filmed(cfg, 4)
    start = time.perf_counter()
    for n in range(2, 11):
        check_filmed(cfg, n)
    assert time.perf_counter() - start < 1.0
