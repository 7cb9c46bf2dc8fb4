"""Motion rules, kinematics and planners: pure functions checked against their definitions."""

import numpy as np
import pytest

from macrostate_mj.chain.motion import (
    WaitForBehind,
    avoidance_velocities,
    body_twist,
    chain_velocities,
    follower_velocity,
    tail_velocity,
    unicycle_commands,
    unicycle_from_holonomic,
    waiting_follower_velocity,
    wheel_speeds,
    wrap_angle,
)
from macrostate_mj.chain.planners import CellPlanner, Grid, GridPlanner, PsiGrid, psi_candidates


def test_wrap_angle_range_and_pi():
    a = wrap_angle(np.linspace(-10, 10, 1001))
    assert np.all(a > -np.pi) and np.all(a <= np.pi)
    assert wrap_angle(-np.pi) == pytest.approx(np.pi)
    assert wrap_angle(3 * np.pi / 2) == pytest.approx(-np.pi / 2)


def test_follower_at_spacing_d_is_still_and_pulled_when_stretched():
    d = 0.3
    p, ahead, behind = np.zeros(2), np.array([d, 0.0]), np.array([-d, 0.0])
    assert np.allclose(follower_velocity(p, ahead, behind, d, 5.0), 0)
    v = follower_velocity(p, np.array([0.4, 0.0]), behind, d, 5.0)
    assert v[0] == pytest.approx(5.0 * 0.1 * 0.4) and v[1] == 0


def test_tail_pulls_toward_neighbour_and_pushes_when_too_close():
    assert tail_velocity(np.zeros(2), np.array([0.5, 0]), 0.3, 2.0)[0] > 0
    assert tail_velocity(np.zeros(2), np.array([0.1, 0]), 0.3, 2.0)[0] < 0


def test_waiting_follower_stops_while_the_robot_behind_lags():
    p, ahead = np.zeros(2), np.array([0.5, 0.0])
    assert np.any(waiting_follower_velocity(p, ahead, np.array([-0.3, 0]), 0.3, 5, 0.05) != 0)
    assert np.all(waiting_follower_velocity(p, ahead, np.array([-0.5, 0]), 0.3, 5, 0.05) == 0)


def test_holding_rear_robots_stop_rather_than_back_away_from_the_robot_ahead():
    """Too close to the robot ahead (within `hold` of d), the lab's rule with `hold` stops a
    Follower and the Tail, where without it both are pushed backwards; farther than d both
    pull; nearer than d - hold both are pushed back again."""
    near = np.array([[0.0, 0], [-0.29, 0], [-0.58, 0]])
    far = np.array([[0.0, 0], [-0.35, 0], [-0.7, 0]])
    held, plain = WaitForBehind(0.05, hold=0.3), WaitForBehind(0.05)
    assert np.all(chain_velocities(near, None, 0.3, 40, 20, followers=held) == 0)
    assert np.all(chain_velocities(near, None, 0.3, 40, 20, followers=plain)[1:, 0] < 0)
    assert np.array_equal(chain_velocities(far, None, 0.3, 40, 20, followers=held),
                          chain_velocities(far, None, 0.3, 40, 20, followers=plain))
    for bad in ({"slack": -0.05}, {"slack": 0.05, "hold": -0.01}, {"slack": float("nan")}):
        with pytest.raises(ValueError, match="followers"):
            WaitForBehind(**bad)
    banded = WaitForBehind(0.05, hold=0.005)
    assert np.all(chain_velocities(near * 1.02, None, 0.3, 40, 20, followers=banded) == 0)
    assert np.all(chain_velocities(near, None, 0.3, 40, 20, followers=banded)[1:, 0] < 0)


def test_chain_velocities_order_head_first():
    pos = np.array([[0.0, 0], [-0.3, 0], [-0.6, 0]])
    vel = chain_velocities(pos, np.array([1.0, 0]), 0.3, 5, 5)
    assert vel[0, 0] == pytest.approx(1.0)
    assert np.allclose(vel[1:], 0)


def test_avoidance_pushes_robots_apart_symmetrically():
    v = avoidance_velocities(np.array([[0.0, 0], [0.1, 0], [5, 5]]), 0.2, 0.1)
    assert v[0, 0] < 0 < v[1, 0]
    assert v[0, 0] == pytest.approx(-v[1, 0])
    assert np.allclose(v[2], 0)


def test_unicycle_turns_toward_reference_and_stops_instead_of_reversing():
    v, w = unicycle_from_holonomic(np.array([0.0, 0.1]), 0.0, 2.0, 0.2)
    assert v == pytest.approx(0, abs=1e-12) and w == pytest.approx(np.pi)
    v, w = unicycle_from_holonomic(np.array([-0.1, 0.01]), 0.0, 2.0, 0.2, allow_reverse=True)
    assert v < 0 and abs(w) < 0.5      # backs up, turning its rear slightly, no half-turn
    v, _ = unicycle_from_holonomic(np.array([-0.1, 0.01]), 0.0, 2.0, 0.2, allow_reverse=False)
    assert v == 0
    assert unicycle_from_holonomic(np.array([0.001, 0]), 0.0, 2.0, 0.2) == (0.0, 0.0)


def test_wheel_speeds_invert_body_twist_and_saturate_keeping_curvature():
    r, track, top = 0.0215, 0.095, 9.3
    left, right = wheel_speeds(0.1, 0.5, r, track, top)
    assert body_twist(left, right, r, track) == pytest.approx((0.1, 0.5))
    left, right = wheel_speeds(1.0, 2.0, r, track, top)
    assert max(abs(left), abs(right)) == pytest.approx(top)
    v, w = body_twist(left, right, r, track)
    assert w / v == pytest.approx(2.0)


def test_psi_candidates_are_ahead_of_the_last_two_cells():
    grid = Grid((2.5, 1.9), (12, 8))
    latest, earlier = 5 + 12 * 3, 4 + 12 * 3       # moving +x along a row
    cands = psi_candidates(grid, latest, earlier)
    assert sorted(c % 12 for c in cands) == [6, 6, 6]
    for c in cands:
        assert grid.adjacent(latest, c) and not grid.adjacent(earlier, c) and c != earlier


def test_grid_planner_draws_waypoints_in_candidate_cells_inside_margin():
    rng = np.random.default_rng(0)
    planner = GridPlanner(Grid((2.5, 1.9), (12, 8)), margin=0.15, reach_radius=0.06)
    pose = np.array([0.0, 0.0, 0.0])
    planner.reset(pose, rng)
    for _ in range(200):
        latest, earlier = planner.memory
        cand = psi_candidates(planner.grid, latest, earlier)
        pose = np.array([*planner.target, 0.0])
        planner.update(pose, 0.0, rng)           # reached: a new waypoint is drawn
        assert np.all(np.abs(planner.target) <= np.array([1.1, 0.8]) + 1e-12)
        assert planner.memory[1] == latest
        # The reached waypoint lay in a candidate cell of the previous memory (or its clip).
        assert planner.memory[0] in cand or np.any(np.abs(pose[:2]) >= [1.1 - 1e-9, 0.8 - 1e-9])


def test_psi_with_a_largest_turn_keeps_the_head_heading_on_and_draws_as_before_at_180():
    """At 180 degrees (the text's Psi) the planner draws exactly what it drew before the key;
    below it, a waypoint more than `max_turn` off the Head's heading is drawn again."""
    grid = Grid((2.5, 1.9), (12, 8))

    def route(max_turn: float, legacy: bool = False) -> list[tuple[float, float]]:
        rng = np.random.default_rng(3)
        planner = GridPlanner(grid, margin=0.15, reach_radius=0.06) if legacy else \
            GridPlanner(grid, margin=0.15, reach_radius=0.06, max_turn=max_turn)
        pose = np.array([0.0, 0.0, 0.0])
        planner.reset(pose, rng)
        turns = []
        for _ in range(300):
            heading = np.arctan2(*(planner.target - pose[:2])[::-1])
            pose = np.array([*planner.target, heading])       # arrived, facing its way
            planner.update(pose, 0.0, rng)
            off = planner.target - pose[:2]
            turns.append(abs(np.degrees(wrap_angle(np.arctan2(off[1], off[0]) - heading))))
        return turns

    assert route(180.0) == route(180.0, legacy=True)
    free, kept = np.array(route(180.0)), np.array(route(60.0))
    assert np.mean(free > 60) > 0.2                    # Psi alone turns far, often
    # (near walls no candidate cell may lie within the turn: the least turn drawn is kept)
    assert np.mean(kept > 60) < np.mean(free > 60) / 3, (np.mean(kept > 60), np.mean(free > 60))
    with pytest.raises(ValueError, match="max_turn must be an angle"):
        PsiGrid((12, 8), max_turn=0.0)


def test_a_head_that_keeps_its_speed_through_turns():
    """turn_speed 0 is the text's v = |u| cos e; 1 keeps |u| through any turn under 90
    degrees; a reference behind a robot that may not reverse stops it either way."""
    u = np.array([[0.05 * np.cos(1.0), 0.05 * np.sin(1.0)], [-0.05, 0.0]])
    theta, v_max, rev = np.zeros(2), np.full(2, 0.1), np.zeros(2, bool)
    v0, w0 = unicycle_commands(u, theta, 1.2, v_max, rev)
    assert v0[0] == pytest.approx(0.05 * np.cos(1.0)) and v0[1] == 0.0
    same, _ = unicycle_commands(u, theta, 1.2, v_max, rev, turn_speed=np.zeros(2))
    assert np.array_equal(same, v0)
    v1, w1 = unicycle_commands(u, theta, 1.2, v_max, rev, turn_speed=np.ones(2))
    assert v1[0] == pytest.approx(0.05) and v1[1] == 0.0 and np.array_equal(w1, w0)
    half, _ = unicycle_commands(u, theta, 1.2, v_max, rev, turn_speed=np.full(2, 0.5))
    assert half[0] == pytest.approx(0.05 * (0.5 + 0.5 * np.cos(1.0)))


def test_cell_planner_redraws_on_entering_a_new_cell():
    rng = np.random.default_rng(1)
    planner = CellPlanner(Grid((3.0, 3.0), (10, 10)), margin=0.2)
    planner.reset(np.array([0.05, 0.05, 0]), rng)
    first = planner.target.copy()
    planner.update(np.array([0.1, 0.1, 0]), 1.0, rng)      # same cell: unchanged
    assert np.array_equal(planner.target, first)
    planner.update(np.array([0.4, 0.1, 0]), 2.0, rng)      # next cell: new nearby centre
    assert planner.grid.adjacent(planner.cell, planner.grid.cell_of(planner.target))


def test_a_start_gap_keeps_rear_robots_still_until_the_robot_ahead_pulls_clearly_away():
    """`start`: a rear robot less than `start` beyond d waits (a parked chain is not tugged
    into turning on the spot); beyond it, it sets off at once at the speed its gain gives (the
    real rear robots' jump); without `start` the rule is bit for bit what it was."""
    just_beyond = np.array([[0.0, 0], [-0.31, 0], [-0.62, 0]])
    clearly = np.array([[0.0, 0], [-0.33, 0], [-0.66, 0]])
    started, plain = WaitForBehind(0.05, start=0.02), WaitForBehind(0.05)
    assert np.all(chain_velocities(just_beyond, None, 0.3, 40, 20, followers=started) == 0)
    assert np.all(chain_velocities(just_beyond, None, 0.3, 40, 20, followers=plain)[1:, 0] > 0)
    assert np.array_equal(chain_velocities(clearly, None, 0.3, 40, 20, followers=started),
                          chain_velocities(clearly, None, 0.3, 40, 20, followers=plain))
    assert np.array_equal(chain_velocities(just_beyond, None, 0.3, 40, 20,
                                           followers=WaitForBehind(0.05, start=0.0)),
                          chain_velocities(just_beyond, None, 0.3, 40, 20, followers=plain))
    with pytest.raises(ValueError, match="followers.start"):
        WaitForBehind(0.05, start=-0.01)
