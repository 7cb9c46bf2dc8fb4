"""`simulate --video` shows the camera's view: the frame through the scenario's lens, with the
overlays where they lie in that distorted image; `view="undistorted"` is the pinhole render."""

import numpy as np
import pytest

from macrostate_mj.chain.scenarios import get_scenario
from macrostate_mj.chain.sim import ChainSim
from macrostate_mj.chain.world import build_world
from viz.video import VideoRecorder


@pytest.fixture(scope="module")
def frames(tmp_path_factory):
    """The e-puck lab (k1 = -0.2) in both views: bare frames, and the cameras behind them."""
    sim = ChainSim(build_world(get_scenario("examples/epuck_lab.toml"), 3))
    sim.reset(np.random.default_rng(0))
    out = {}
    for view in ("camera", "undistorted"):
        rec = VideoRecorder(tmp_path_factory.mktemp(view) / "v.mp4", sim, overlays=(), view=view)
        out[view] = (rec.frame(sim)[:, :, ::-1], rec.camera)
        rec.abort()
    return sim, out


def _top_edge(rgb: np.ndarray, u: int) -> int:
    """The first row of the bright floor in column u, from the top."""
    return int(np.argmax(rgb[:, u].mean(axis=1) > 150))


def test_a_straight_wall_bends_in_the_camera_view_only(frames):
    _, views = frames
    straight, bent = views["undistorted"][0], views["camera"][0]
    assert abs(_top_edge(straight, 640) - _top_edge(straight, 160)) <= 1
    assert _top_edge(bent, 160) - _top_edge(bent, 640) > 10      # barrel: the edge sags away
    assert not np.array_equal(straight, bent)


def test_overlays_sit_on_the_robots_in_the_distorted_frame(frames):
    sim, views = frames
    rgb, camera = views["camera"]
    xyz = np.column_stack([sim.poses[:, :2], np.full(sim.n, sim.world.marker_height)])
    uv = camera.world_to_pixel(xyz)
    pinhole = views["undistorted"][1].world_to_pixel(xyz)
    assert np.hypot(*(uv - pinhole).T).min() > 5        # the lens moves them visibly
    for (u, v), colour in zip(uv, sim.world.colours, strict=True):
        assert np.abs(rgb[int(round(v)), int(round(u))].astype(int) - colour * 255).max() < 60
