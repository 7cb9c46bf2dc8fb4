"""`simulate`, `export-mjcf` and `bench` from the command line, as a user runs them."""

import json

import cv2
import mujoco
import numpy as np
import pyarrow.parquet as pq
import pytest
from clitools import assert_clean_error, cli

from macrostate_mj.chain.scenarios import get_scenario
from macrostate_mj.chain.sim import ChainSim
from macrostate_mj.chain.world import build_world
from macrostate_mj.vision.camera import OverheadRenderer, PinholeCamera


def test_simulate_writes_long_format_poses_and_manifest(tmp_path):
    out = tmp_path / "run"
    res = cli("simulate", "--scenario", "lab", "--robots", "4", "--seconds", "10", "--seed", "3",
              "--out", str(out))
    assert res.returncode == 0, res.stderr
    table = pq.read_table(out / "poses.parquet").to_pandas()
    assert list(table.columns[:6]) == ["t", "step", "robot", "x", "y", "theta"]
    assert table.robot.iloc[:4].tolist() == ["H", "F1", "F2", "T"]
    assert len(table) == 20 * 4                          # 2 Hz for 10 s, 4 robots
    assert table.theta.between(-np.pi, np.pi, inclusive="right").all()
    assert table.x.abs().max() < 1.25 and table.y.abs().max() < 0.95
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["seed"] == 3 and manifest["config"]["scenario"]["name"] == "lab"
    assert {"build", "run"} <= set(manifest["timings_s"]) and manifest["version"]
    assert "mujoco" in manifest["versions"] and manifest["machine"]["cores"] >= 1


def test_same_seed_bit_identical_parquet_other_seed_differs(tmp_path):
    tables = []
    for name, seed in (("a", "1"), ("b", "1"), ("c", "2")):
        res = cli("simulate", "--robots", "3", "--seconds", "8", "--seed", seed,
                  "--out", str(tmp_path / name))
        assert res.returncode == 0, res.stderr
        tables.append(pq.read_table(tmp_path / name / "poses.parquet"))
    assert tables[0].equals(tables[1])
    assert not tables[0].equals(tables[2])


def _rrd_rows(rrd) -> dict[str, int]:
    """Rows logged per entity, from `rerun rrd print` (the recording as rerun reads it)."""
    import re
    import shutil
    import subprocess
    import sys
    from pathlib import Path

    exe = shutil.which("rerun", path=str(Path(sys.executable).parent))
    out = subprocess.run([exe, "rrd", "print", str(rrd)], capture_output=True, text=True,
                         check=True, env={"RERUN_ANALYTICS": "0"}).stdout
    rows: dict[str, int] = {}
    for n, entity in re.findall(r"with (\d+) rows .*? - (/\S+) - ", out):
        rows[entity] = rows.get(entity, 0) + int(n)
    return rows


def test_video_and_rerun_outputs(tmp_path):
    video, rrd = tmp_path / "v.mp4", tmp_path / "r.rrd"
    res = cli("simulate", "--robots", "3", "--seconds", "3", "--out", str(tmp_path / "o"),
              "--video", str(video), "--rerun", str(rrd), "--track")
    assert res.returncode == 0, res.stderr
    cap = cv2.VideoCapture(str(video))
    assert int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == 30
    assert int(cap.get(cv2.CAP_PROP_FOURCC)).to_bytes(4, "little") == b"h264"  # plays in browsers
    ok, frame = cap.read()
    assert ok and frame.shape == (570, 750, 3)
    assert rrd.read_bytes()[:4] == b"RRF2"
    rows = _rrd_rows(rrd)
    poses = rows["/world/robots"]
    assert poses == 6 and rows["/camera/overhead"] == poses       # a frame per pose (2 Hz)
    assert rows["/world/tracked"] == poses and rows["/metrics/tracker_error_mm/H"] >= poses - 1
    assert "/metrics/spacing_m/H-F1" in rows and "/metrics/speed_m_s/T" in rows
    assert rows["/world3d/H/thymio"] == poses and any(e.startswith("/world3d/H/thymio/geom")
                                                      for e in rows)   # MJCF geometry
    assert any(e.startswith("/view") for e in rows)               # the layout it opens on
    assert not list(tmp_path.glob(".*part*"))            # no temporary left behind


def test_export_mjcf_loads_in_plain_mujoco(tmp_path):
    out = tmp_path / "scene.xml"
    res = cli("export-mjcf", "--scenario", "webots", "--robots", "6", "--out", str(out))
    assert res.returncode == 0, res.stderr
    model = mujoco.MjModel.from_xml_path(str(out))
    assert model.nu == 12 and model.body("T/thymio").id > 0


@pytest.mark.parametrize("args,words", [
    (["--scenario", "moon"], ["moon", "lab"]),
    (["--robots", "1"], ["--robots", "2"]),
    (["--robots", "400"], ["400", "fewer"]),
    (["--seconds", "0"], ["--seconds", "positive"]),
    (["--seconds", "abc"], ["--seconds"]),
])
def test_bad_input_one_line_exit_2_nothing_written(tmp_path, args, words):
    out = tmp_path / "never"
    assert_clean_error(cli("simulate", "--out", str(out), *args), *words)
    assert not out.exists()


def test_existing_output_needs_overwrite_and_unwritable_path(tmp_path):
    out = tmp_path / "run"
    assert cli("simulate", "--robots", "2", "--seconds", "1", "--out", str(out)).returncode == 0
    before = (out / "poses.parquet").read_bytes()
    assert_clean_error(cli("simulate", "--robots", "2", "--seconds", "1", "--seed", "9",
                           "--out", str(out)), "--overwrite")
    assert (out / "poses.parquet").read_bytes() == before
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    assert_clean_error(cli("simulate", "--robots", "2", "--seconds", "1",
                           "--out", str(blocker / "run")), "cannot create", "is a file")
    assert_clean_error(cli("simulate", "--robots", "2", "--seconds", "1", "--out",
                           str(tmp_path / "ok"), "--video", str(blocker / "v.mp4")), "is a file")
    assert not (tmp_path / "ok").exists()


def test_camera_model_projects_markers_onto_their_pixels():
    world = build_world(get_scenario("lab"), 5)
    sim = ChainSim(world)
    sim.reset(np.random.default_rng(4))
    cam = PinholeCamera.from_model(world.model, sim.data)
    assert cam.px_per_m == pytest.approx(300, rel=0.01)       # 3 px/cm at the floor
    poses = sim.poses
    xyz = np.column_stack([poses[:, :2], np.full(5, world.marker_height)])
    uv = cam.world_to_pixel(xyz)
    with OverheadRenderer(world.model) as renderer:
        rgb = renderer.render(sim.data).astype(int)
    for (u, v), colour in zip(uv, world.colours, strict=True):
        assert np.abs(rgb[int(round(v)), int(round(u))] - colour * 255).max() < 60
    back = cam.pixel_to_world(uv, world.marker_height)
    assert np.allclose(back, poses[:, :2], atol=1e-9)
    h = cam.homography(world.marker_height)
    proj = (h @ np.column_stack([poses[:, :2], np.ones(5)]).T).T
    assert np.allclose(proj[:, :2] / proj[:, 2:], uv, atol=1e-6)


def test_bench_prints_ratios_against_limits_in_one_schema():
    from macrostate_mj.app.bench import FIELDS

    res = cli("bench", "--json", "--only", "sim", "--only", "render", "--only", "flow")
    assert res.returncode == 0, res.stderr
    figs = [json.loads(line) for line in res.stdout.splitlines()]
    assert {f["suite"] for f in figs} == {"sim", "render", "flow"}
    assert all(set(FIELDS) <= set(f) and isinstance(f["config"], str) for f in figs), figs
    steps = next(f for f in figs if f["name"] == "sim_steps_per_s")
    assert steps["ratio"] == pytest.approx(steps["value"] / steps["limit"], rel=1e-3)
    assert steps["ratio"] > 0.5
    table = cli("bench", "--only", "render")
    assert table.returncode == 0 and "ratio" in table.stdout, table.stderr


def test_the_health_suite_counts_what_the_health_figures_cost():
    """Its figures in the one schema (speed itself is the bench's, not a test's)."""
    from macrostate_mj.app.bench import FIELDS
    from macrostate_mj.app.bench.collect import bench_health

    paired, share = bench_health(seconds=3.0, robots=3)
    assert set(FIELDS) <= set(paired) and paired["ratio"] > 0
    assert share["name"] == "health_share_of_tracked_run" and 0 < share["value"] < 1


def test_tracked_log_carries_the_truth_at_tracking_time_and_units(tmp_path):
    """x_trk - x_truth_trk is the tracker's error plus the drawn marker jitter (mm); x_trk - x
    also holds the motion between the frame and the log tick, which is what made a good tracker
    read as a bad one."""
    out = tmp_path / "run"
    res = cli("simulate", "--robots", "3", "--seconds", "20", "--seed", "3", "--track",
              "--out", str(out))
    assert res.returncode == 0, res.stderr
    table = pq.read_table(out / "poses.parquet")
    assert table.schema.field("x_truth_trk").metadata[b"unit"] == b"m"
    assert b"arena centre" in table.schema.metadata[b"frame"]
    col = {name: table.column(name).to_numpy() for name in table.column_names
           if name != "robot"}
    seen = np.isfinite(col["x_trk"])
    own = np.hypot(col["x_trk"] - col["x_truth_trk"], col["y_trk"] - col["y_truth_trk"])[seen]
    lagged = np.hypot(col["x_trk"] - col["x"], col["y_trk"] - col["y"])[seen]
    assert seen.mean() > 0.9
    # the image pipeline's own error, plus the lab's marker jitter (a Rayleigh median 1.18 σ)
    jitter = get_scenario("lab").marker_jitter
    assert np.median(own) < 0.0015 + 1.2 * jitter and np.median(own) < np.median(lagged)
    assert (col["t_trk"][seen] <= col["t"][seen] + 1e-9).all()


def test_tracker_and_collect_suites_share_the_schema():
    """The suites too slow for `bench` in a test, run small: the same keys on every figure."""
    from macrostate_mj.app.bench import FIELDS
    from macrostate_mj.app.bench.collect import bench_collect, bench_tracker

    figs = bench_tracker(episodes=1, seconds=3.0, robots=3) + bench_collect(
        minutes=0.1, robots=3, repeats=1)
    assert all(set(FIELDS) <= set(f) and isinstance(f["config"], str) for f in figs), figs
    names = {f["name"] for f in figs}
    assert {"collect_stage_imaging_in_windows_ms_per_frame",
            "collect_stage_tracking_in_windows_ms_per_frame"} <= names
    assert all(0 < f["ratio"] for f in figs if f["ratio"] is not None)


def test_iogen_suite_times_bf16_against_float32_in_the_same_run():
    from macrostate_mj.app.bench import FIELDS
    from macrostate_mj.app.bench.iogen import bench_iogen

    figs = {f["name"]: f for f in bench_iogen(n_train=48, threads=1)}
    assert all(set(FIELDS) <= set(f) for f in figs.values()), figs
    fp32, bf16 = (figs["iogen_one_split_minutes_estimate"],
                  figs["iogen_bf16_one_split_minutes_estimate"])
    assert bf16["limit"] == round(fp32["value"], 4) and bf16["value"] > 0
    assert (fp32["limit_kind"], bf16["limit_kind"]) == ("target", "measured")
    assert bf16["ratio"] == pytest.approx(bf16["limit"] / bf16["value"], rel=1e-3)
