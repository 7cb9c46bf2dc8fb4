"""The one pixel convention: pixel centres at integers, the image centre at (w - 1) / 2."""

import numpy as np
import pytest

from macrostate_mj.core.pixels import focal_length, project


def test_projection_of_a_camera_looking_straight_down():
    cam_pos, cam_mat = np.array([0, 0, 0.335]), np.eye(3)
    f = focal_length(256, 28)
    uv = project(np.array([[0, 0, 0], [0.05, 0, 0], [0, 0.05, 0]]), cam_pos, cam_mat, f, 256, 256)
    assert np.allclose(uv[0], [127.5, 127.5])            # between the two middle pixels
    assert uv[1, 0] > 127.5 and np.isclose(uv[1, 1], 127.5)  # +x is to the right
    assert uv[2, 1] < 127.5                                # +y is up in the image
    # the image's top edge (v = -0.5) lies at half the field of view
    top = np.array([[0, 0.335 * np.tan(np.radians(14)), 0]])
    assert project(top, cam_pos, cam_mat, f, 256, 256)[0, 1] == pytest.approx(-0.5)
