"""Fig 2.9's measures: an estimate pulled toward a curve's centre reads as an inside bias, one
pushed outward as negative, and the largest-error share names the robot that errs most."""

import numpy as np

from estimators.retlo.curves import inside_bias, largest_error_share


def _circle(n_robots: int = 5, steps: int = 26, left: bool = True) -> np.ndarray:
    """Robots one behind the other on a circle of radius 1 m, moving 0.08 rad a step."""
    sign = 1.0 if left else -1.0
    angle = sign * (0.08 * np.arange(steps)[:, None] - 0.3 * np.arange(n_robots)[None, :])
    world = np.zeros((1, steps, n_robots, 3))
    world[0, :, :, 0], world[0, :, :, 1] = np.cos(angle), np.sin(angle)
    return world


def _pulled(world: np.ndarray, toward_centre: float) -> np.ndarray:
    est = world.copy()
    est[..., :2] *= 1.0 - toward_centre        # the centre is the origin
    est[:, :, -2:] = np.nan                    # the Tail and its neighbour: not estimated
    return est


def test_an_estimate_toward_the_centre_is_an_inside_bias_on_either_turn():
    for left in (True, False):
        world = _circle(left=left)
        inward = inside_bias(_pulled(world, 0.02), world)
        outward = inside_bias(_pulled(world, -0.02), world)
        assert abs(inward["pooled"]["inside_cm"] - 2.0) < 0.05
        assert abs(outward["pooled"]["inside_cm"] + 2.0) < 0.05
        assert set(inward) == {"H", "F2", "F3", "pooled"}
        assert inward["H"]["steps"] == 24


def test_a_straight_path_or_a_waiting_robot_has_no_inside():
    world = np.zeros((1, 26, 5, 3))
    world[0, :, :, 0] = 0.05 * np.arange(26)[:, None] - 0.3 * np.arange(5)[None, :]
    assert inside_bias(_pulled(world, 0.02), world)["pooled"]["steps"] == 0
    still = np.zeros((1, 26, 5, 3))
    assert inside_bias(_pulled(still, 0.02), still)["pooled"]["steps"] == 0


def test_the_largest_error_share_names_the_robot_that_errs_most():
    world = _circle()
    est = _pulled(world, 0.0)
    est[:, :, 1, 0] += 0.1                     # file F1: the report's F3
    est[:, :10, 0, 0] += 0.2                   # the Head, at the first 10 instants only
    share = largest_error_share(est, world)
    assert share == {"H": 10 / 26, "F3": 16 / 26, "F2": 0.0}
