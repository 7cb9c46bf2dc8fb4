"""`simulate --camera-video` then `track`: the simulator's tracker, offline, on the frames it was
handed online, as a lab would run it on its own footage."""

import json

import numpy as np
import pyarrow.parquet as pq
import pytest
from clitools import assert_clean_error, cli, cli_inprocess

STILL = 'extends = "lab"\nname = "lab_still"\n\n[noise]\nmarker_jitter = 0.0\n'


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """A short tracked run of the lab without marker jitter (so the online poses are exactly
    the tracker's), its camera video, and `track` on that video."""
    tmp = tmp_path_factory.mktemp("rec")
    scenario = tmp / "lab_still.toml"
    scenario.write_text(STILL)
    common = ["--scenario", str(scenario), "--robots", "3", "--seconds", "5", "--seed", "2",
              "--track"]
    res = cli("simulate", *common, "--camera-video", str(tmp / "cam.mp4"),
              "--out", str(tmp / "run"))
    assert res.returncode == 0, res.stderr
    plain = cli("simulate", *common, "--out", str(tmp / "plain"))   # lazy, windowed
    assert plain.returncode == 0, plain.stderr
    res = cli("track", str(tmp / "cam.mp4"), "--scenario", str(scenario), "--robots", "3",
              "--out", str(tmp / "trk"))
    assert res.returncode == 0, res.stderr
    assert "detected  H 100.0%" in res.stdout
    return tmp


def test_tracking_footage_as_the_wrong_team_is_refused(recorded):
    """Colour markers are chosen by team size: as 4 robots, a 3-robot video's markers would be
    tracked as other robots' or missed; its frames show 3, and the track is refused."""
    res = cli("track", str(recorded / "cam.mp4"), "--scenario", str(recorded / "lab_still.toml"),
              "--robots", "4", "--out", str(recorded / "wrong"))
    assert_clean_error(res, "shows 3 colour markers", "--robots is 4", "give --robots 3")
    assert not (recorded / "wrong").exists()


def test_filming_the_camera_leaves_the_run_as_it_was(recorded):
    assert pq.read_table(recorded / "run" / "poses.parquet").equals(
        pq.read_table(recorded / "plain" / "poses.parquet"))


def test_offline_track_agrees_with_the_online_tracker(recorded):
    import cv2

    times = np.loadtxt(recorded / "cam.times.csv", delimiter=",", skiprows=1)[:, 1]
    cap = cv2.VideoCapture(str(recorded / "cam.mp4"))
    assert int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == len(times) >= 19   # 4 Hz, less drops
    ok, frame = cap.read()
    assert ok and frame.shape == (570, 750, 3)
    online = pq.read_table(recorded / "run" / "poses.parquet").to_pandas()
    offline = pq.read_table(recorded / "trk" / "poses.parquet").to_pandas()
    assert np.allclose(offline.t.unique(), times) and offline.x.isna().all()
    assert offline.detected.mean() >= 0.95
    on = online[online.detected].assign(key=lambda d: d.t_trk.round(6))
    off = offline[offline.detected].assign(key=lambda d: d.t.round(6))
    both = on.merge(off, on=["key", "robot"], suffixes=("", "_off"))
    assert len(both) >= 0.9 * len(on)
    apart = np.hypot(both.x_trk_off - both.x_trk, both.y_trk_off - both.y_trk)
    error = np.hypot(both.x_trk_off - both.x_truth_trk, both.y_trk_off - both.y_truth_trk)
    assert np.median(apart) < 0.0005 and np.median(error) < 0.003
    manifest = json.loads((recorded / "trk" / "manifest.json").read_text())
    assert manifest["command"] == "track" and manifest["frames"] == len(times)


def _tiny_video(path, size=(64, 48)):
    from macrostate_mj.core.io import Mp4Writer

    with Mp4Writer(path, 4, size) as w:
        for _ in range(3):
            w.write(np.zeros((size[1], size[0], 3), np.uint8))
    return path


@pytest.mark.parametrize("case,words", [
    ("missing", ["none.mp4", "does not exist"]),
    ("garbage", ["cannot read video"]),
    ("size", ["64 x 48", "750 x 570"]),
    ("robots1", ["--robots"]),
    ("robots400", ["--robots", "400"]),
])
def test_bad_input_one_line_exit_2_nothing_written(tmp_path, capsys, case, words):
    video, robots = tmp_path / "v.mp4", "3"
    if case == "missing":
        video = tmp_path / "none.mp4"
    elif case == "garbage":
        video.write_bytes(b"not a video at all" * 50)
    else:
        _tiny_video(video, (750, 570) if case.startswith("robots") else (64, 48))
        robots = case.removeprefix("robots") if case.startswith("robots") else robots
    out = tmp_path / "never"
    code, _, err = cli_inprocess(capsys, "track", str(video), "--robots", robots,
                                 "--out", str(out))
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and "Traceback" not in err, err
    assert all(w in lines[0] for w in words), lines[0]
    assert not out.exists()


def test_camera_video_needs_track(tmp_path, capsys):
    out = tmp_path / "never"
    code, _, err = cli_inprocess(capsys, "simulate", "--robots", "2", "--seconds", "1", "--out",
                                 str(out), "--camera-video", str(tmp_path / "c.mp4"))
    assert code == 2 and len(err.strip().splitlines()) == 1 and "--track" in err, err
    assert not out.exists() and not (tmp_path / "c.mp4").exists()
