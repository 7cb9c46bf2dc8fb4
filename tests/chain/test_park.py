"""The `park` planner: the Head drives to a point and stays, the chain lining up behind it (a
parked team beside an obstacle, for `soak --track`)."""

import numpy as np
from clitools import assert_clean_error, cli

from macrostate_mj.chain.scenario_file import load_scenario
from macrostate_mj.chain.sim import simulate_poses
from macrostate_mj.chain.world import build_world

PARKED = 'extends = "lab"\nname = "parked"\n\n[planner]\nkind = "park"\npoint = [{x}, 0.3]\n'


def test_the_head_parks_at_its_point_and_stays(tmp_path):
    path = tmp_path / "parked.toml"
    path.write_text(PARKED.format(x=0.6))
    cfg = load_scenario(path)
    _, log = simulate_poses(build_world(cfg, 3), 40.0, 0)
    head = log.arrays()[1][:, 0, :2]
    assert np.hypot(*(head[-1] - [0.6, 0.3])) < 2 * cfg.reach_radius
    assert np.hypot(*(head[-1] - head[-10])) < 0.01          # standing still at the end


def test_a_park_point_outside_the_arena_is_one_line_exit_2(tmp_path):
    path = tmp_path / "parked.toml"
    path.write_text(PARKED.format(x=1.5))
    res = cli("scenario", "check", str(path))
    assert_clean_error(res, "planner.point [1.5, 0.3] lies outside the 2.5 x 1.9 m arena",
                       "move it inside")


def test_a_park_point_against_an_obstacle_is_one_line_exit_2(tmp_path):
    path = tmp_path / "parked.toml"
    path.write_text(PARKED.format(x=0.6) + '\n[arena]\nobstacles = [{shape = "box", '
                    'pos = [0.62, 0.3], size = [0.2, 0.2, 0.2]}]\n')
    res = cli("scenario", "check", str(path))
    assert_clean_error(res, "lies on or against arena.obstacles[0]", "park beside it")
