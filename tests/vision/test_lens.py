"""Lens distortion: the render is bent by the scenario's lens, the tracker undoes it with its
calibration, and an ideal lens changes nothing."""

from dataclasses import replace

import numpy as np
import pytest

from macrostate_mj.chain.scenario_file import load_scenario, to_toml
from macrostate_mj.chain.scenarios import get_scenario
from macrostate_mj.chain.sim import ChainSim, Every
from macrostate_mj.chain.world import build_world
from macrostate_mj.core.errors import UserError
from macrostate_mj.vision.camera import (
    Lens,
    OverheadRenderer,
    PinholeCamera,
    distort_pixels,
    undistort_pixels,
)
from macrostate_mj.vision.camera_chain import CameraChain
from macrostate_mj.vision.imaging import NoiseConfig, draw_episode
from macrostate_mj.vision.tracker import Tracker

BARREL = (-0.2, 0.0, 0.0, 0.0)
LENS_TOML = ('extends = "lab"\nname = "bent"\n[arena]\nsize = [4.0, 3.0]\n[camera]\nheight = 3.0\n'
             'resolution = [1280, 960]\nfovy = "auto"\ndistortion = [-0.2, 0, 0, 0]\n')


def test_an_ideal_lens_leaves_frames_and_poses_bit_identical():
    world = build_world(get_scenario("lab"), 3)
    sim = ChainSim(world)
    sim.reset(np.random.default_rng(0))
    with OverheadRenderer(world.model) as plain, \
            OverheadRenderer(world.model, distortion=(0.0, 0.0, 0.0, 0.0)) as ideal:
        assert ideal.lens.maps is None
        frame = plain.render(sim.data)
        assert np.array_equal(ideal.render(sim.data), frame)
    bare = Tracker.for_world(world, sim.data)
    zero = Tracker.for_world(world, sim.data, (0.0, 0.0, 0.0, 0.0))
    assert np.array_equal(bare.track(frame).poses, zero.track(frame).poses, equal_nan=True)
    uv = np.array([[10.0, 20.0], [700.5, 500.25]])
    assert np.array_equal(zero.camera.pixel_to_world(uv, 0.05),
                          bare.camera.pixel_to_world(uv, 0.05))


def test_no_distortion_error_draws_nothing_more():
    a, b = np.random.default_rng(1), np.random.default_rng(1)
    ep = draw_episode(NoiseConfig(), a)
    draw_episode(NoiseConfig(distortion_error=0.0), b)
    assert a.random() == b.random() and ep.calibrated(BARREL) == BARREL
    off = draw_episode(NoiseConfig(distortion_error=0.05), np.random.default_rng(1))
    k1, k2, p1, p2 = off.calibrated((-0.2, 0.1, 0.001, 0.002))
    assert k1 != -0.2 and k2 != 0.1 and (p1, p2) == (0.001, 0.002)


@pytest.fixture(scope="module")
def lens():
    return Lens(1280, 960, 960.0, BARREL)      # maps: 0.7 s, once


@pytest.mark.parametrize("ideal", [(1100.0, 820.0), (640.3, 479.8), (150.7, 90.2)])
def test_a_point_bent_by_the_render_comes_back_through_the_tracker(lens, ideal):
    """A blob drawn in the pinhole image at `ideal`, remapped by the render's lens, found in the
    distorted frame (intensity centroid) and undistorted by the calibrated camera: within 0.1 px.
    """
    u, v = np.meshgrid(np.arange(1280.0), np.arange(960.0))
    blob = 250 * np.exp(-((u - ideal[0]) ** 2 + (v - ideal[1]) ** 2) / (2 * 2.0**2))
    frame = lens.apply(np.repeat(blob.astype(np.uint8)[..., None], 3, axis=2))[..., 0]
    w = frame.astype(float)
    seen = np.array([(w * u).sum(), (w * v).sum()]) / w.sum()
    moved = np.linalg.norm(seen - ideal)
    back = undistort_pixels(seen, lens.k, BARREL)
    assert np.linalg.norm(back - ideal) < 0.1
    assert moved > 0.5 or ideal == (640.3, 479.8)      # the lens did move the off-centre ones
    assert np.allclose(distort_pixels(back, lens.k, BARREL), seen, atol=1e-6)


def test_the_calibrated_camera_maps_floor_to_pixels_and_back():
    cam = PinholeCamera(1280, 960, 960.0, np.array([0.0, 0.0, 3.0]),
                        np.diag([1.0, -1.0, -1.0]), BARREL)
    xy = np.array([[1.9, 1.4], [-1.2, 0.3], [0.0, 0.0]])
    uv = cam.world_to_pixel(np.column_stack([xy, np.full(3, 0.05)]))
    assert np.allclose(cam.pixel_to_world(uv, 0.05), xy, atol=1e-9)
    ideal = PinholeCamera(1280, 960, 960.0, cam.position, cam.rotation)
    assert np.linalg.norm(ideal.pixel_to_world(uv, 0.05)[0] - xy[0]) > 0.1   # it matters


def test_a_scenario_file_with_distortion_round_trips(tmp_path):
    path = tmp_path / "bent.toml"
    path.write_text(LENS_TOML)
    cfg = load_scenario(path)
    assert cfg.camera.distortion == BARREL
    text = to_toml(cfg)
    assert "distortion = [-0.2, 0.0, 0.0, 0.0]" in text
    again = tmp_path / "again.toml"
    again.write_text(text)
    assert load_scenario(again) == cfg
    assert load_scenario("lab").camera.distortion == (0.0, 0.0, 0.0, 0.0)
    path.write_text(LENS_TOML.replace("[-0.2, 0, 0, 0]", "[-0.2, 0]"))
    with pytest.raises(UserError, match="camera.distortion"):
        load_scenario(path)


def test_the_tracker_undoes_the_lens_on_rendered_frames():
    """Lab, its camera given a strong barrel lens, clean imaging: tracked to under a pixel
    (3.3 mm) with the lens calibrated; centimetres off at the edges when it is ignored."""
    lab = get_scenario("lab")
    cfg = lab.with_overrides(camera=replace(lab.camera, distortion=BARREL), marker_jitter=0.0)
    world = build_world(cfg, 3)
    sim = ChainSim(world)
    sim.reset(np.random.default_rng(3))
    chain = CameraChain(sim, NoiseConfig.none())
    chain.start(np.random.default_rng(4))
    naive = Tracker.for_world(world, sim.data, (0.0, 0.0, 0.0, 0.0))
    errors, naive_errors = [], []

    def check(s: ChainSim) -> None:
        chain.capture(s)
        ok = chain.detected
        errors.extend(np.linalg.norm(chain.latest[ok, :2] - s.poses[ok, :2], axis=1))
        frame = chain.renderer.render(s.data)
        det = naive.track(frame)
        naive_errors.extend(np.linalg.norm(det.poses[det.detected, :2]
                                           - s.poses[det.detected, :2], axis=1))

    try:
        sim.run(3.0, [Every(0.5, check)])
    finally:
        chain.close()
    assert len(errors) >= 15 and max(errors) < 3.3e-3
    assert max(naive_errors) > 10e-3


def test_the_render_and_the_scenario_check_share_one_forward_lens_model():
    """`distort_pixels` is `core.pixels.distort_normalized` in pixels, and its Jacobian
    determinant (what the scenario's fold check reads) matches central differences."""
    from macrostate_mj.core.pixels import distort_normalized, distortion_jacobian_det

    lens = (-0.2, 0.05, 0.003, -0.002)
    k = np.array([[960.0, 0.0, 639.5], [0.0, 960.0, 479.5], [0.0, 0.0, 1.0]])
    xy = np.random.default_rng(0).uniform(-0.8, 0.8, (50, 2))
    xd, yd = distort_normalized(xy[:, 0], xy[:, 1], lens)
    uv = distort_pixels(xy * 960.0 + [639.5, 479.5], k, lens)
    assert np.allclose(uv, np.column_stack([xd, yd]) * 960.0 + [639.5, 479.5], atol=1e-9)
    h = 1e-6
    cols = []
    for d in ([h, 0.0], [0.0, h]):
        plus = np.column_stack(distort_normalized(*(xy + d).T, lens))
        minus = np.column_stack(distort_normalized(*(xy - d).T, lens))
        cols.append((plus - minus) / (2 * h))
    numeric = cols[0][:, 0] * cols[1][:, 1] - cols[1][:, 0] * cols[0][:, 1]
    assert np.allclose(distortion_jacobian_det(xy[:, 0], xy[:, 1], lens), numeric, atol=1e-6)


@pytest.mark.parametrize(("lens", "folds"), [((-0.2, 0.0, 0.0, 0.0), False),
                                              ((-0.35, 0.0, 0.0, 0.0), True)])
def test_a_lens_the_check_calls_folded_is_one_the_render_cannot_invert(lens, folds):
    """The e-puck lab's 1280 x 960 camera (focal 960 px): k1 = -0.2 inverts to 1e-6 px at every
    image corner; k1 = -0.35 cannot reach them (its distorted radius peaks at 625 px of the
    corners' 800), so the render's sources there are wrong by ~190 px, and the check says so."""
    from macrostate_mj.core.pixels import lens_fold

    k = np.array([[960.0, 0.0, 639.5], [0.0, 960.0, 479.5], [0.0, 0.0, 1.0]])
    corners = np.array([[0.0, 0.0], [1279.0, 959.0], [0.0, 959.0], [1279.0, 0.0]])
    back = distort_pixels(undistort_pixels(corners, k, lens), k, lens)
    assert (np.linalg.norm(back - corners, axis=1).max() > 100) == folds
    assert (lens_fold(640 / 960, 480 / 960, lens) is not None) == folds
