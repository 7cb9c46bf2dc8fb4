"""`track` on footage that could be mislabelled: frame times that survive re-encoding (the camera
video stamps each frame with the time it was taken; a video whose times cannot be trusted is
refused) and a --robots the frames contradict (refused before anything is tracked). Small
cameras and seconds-long recordings, so each case costs a second or two."""

import json
from fractions import Fraction

import av
import numpy as np
import pyarrow.parquet as pq
import pytest
from clitools import assert_clean_error, cli, cli_inprocess

SMALL = """extends = "lab"
name = "{name}"

[arena]
size = [1.2, 0.9]

[camera]
resolution = [480, 360]
fovy = "auto"

[rates]
log_hz = 4

[noise]
marker_jitter = 0.0
drop_prob = {drop}
"""
TAGS = '\n[markers]\nkind = "aruco"\n'


@pytest.fixture(scope="module")
def footage(tmp_path_factory):
    """A 4-robot colour recording whose frame 10 was dropped (seed 2, drop_prob 0.15: checked
    below), its tracked run (the truth at each frame's time), and a 4-robot tag recording."""
    tmp = tmp_path_factory.mktemp("footage")
    (tmp / "drop.toml").write_text(SMALL.format(name="small_drop", drop=0.15))
    (tmp / "tags.toml").write_text(SMALL.format(name="small_tags", drop=0.0) + TAGS)
    for name, seconds in (("drop", 6), ("tags", 3)):
        res = cli("simulate", "--scenario", str(tmp / f"{name}.toml"), "--robots", "4",
                  "--seconds", str(seconds), "--seed", "2", "--track", "--camera-video",
                  str(tmp / f"{name}.mp4"), "--out", str(tmp / f"run_{name}"))
        assert res.returncode == 0, res.stderr
    return tmp


def _times(path):
    return np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)[:, 1]


def _stamps(video):
    with av.open(str(video)) as c:
        return np.array([f.time for f in c.decode(video=0)])


def _reencode(src, dst, codec, mode):
    """Re-encode with PyAV in a 1 ms time base: `keep` each frame's time, `even` re-stamped at
    the camera's 4 Hz, `half` every other frame re-stamped at 2 Hz."""
    tb = Fraction(1, 1000)
    with av.open(str(src)) as inp:
        frames = [(f.time, f.to_ndarray(format="rgb24")) for f in inp.decode(video=0)]
    rate = Fraction(2 if mode == "half" else 4)
    frames = frames[::2] if mode == "half" else frames
    with av.open(str(dst), "w") as out:
        stream = out.add_stream(codec, rate=rate)
        stream.height, stream.width = frames[0][1].shape[:2]
        stream.pix_fmt = "yuv420p"
        stream.codec_context.time_base = tb
        for k, (t, rgb) in enumerate(frames):
            frame = av.VideoFrame.from_ndarray(rgb, format="rgb24")
            frame.pts = round((t if mode == "keep" else k / rate) / tb)
            frame.time_base = tb
            for packet in stream.encode(frame):
                out.mux(packet)
        for packet in stream.encode(None):
            out.mux(packet)
    return dst


def _track(capsys, video, scenario, out, *extra, robots="4"):
    return cli_inprocess(capsys, "track", str(video), "--scenario", str(scenario), "--robots",
                         robots, "--out", str(out), *extra)


def _error_mm(track, run):
    """The offline track's position error against the truth at the time it claims (mm): the
    online run logs every frame (log_hz = the frame rate) with the truth at its time."""
    off = pq.read_table(track / "poses.parquet").to_pandas()
    on = pq.read_table(run / "poses.parquet").to_pandas().dropna(subset=["t_trk"])
    on = on.assign(key=(on.t_trk * 1000).round().astype(int)).drop_duplicates(["key", "robot"])
    off = off[off.detected].assign(key=lambda d: (d.t * 1000).round().astype(int))
    both = off.merge(on, on=["key", "robot"], suffixes=("_off", ""))
    assert len(both) >= 0.9 * len(off)
    return np.hypot(both.x_trk_off - both.x_truth_trk, both.y_trk_off - both.y_truth_trk) * 1e3


def test_the_camera_video_stamps_each_frame_with_its_time(footage):
    times = _times(footage / "drop.times.csv")
    assert np.isclose(np.diff(times), 0.5).sum() == 1        # the dropped frame's gap
    assert np.allclose(_stamps(footage / "drop.mp4"), times, atol=1e-5)


def test_stamps_leave_the_pixels_as_they_were(tmp_path):
    """The stamps change the container, never the frames: x264's rate control keeps to the
    nominal rate (`force-cfr`), so a gap decodes to the pixels evenly stamped frames give."""
    from viz.video import CameraMp4Writer

    rng = np.random.default_rng(0)
    frames = [(rng.integers(0, 4, (48, 64, 3)) * 60).astype(np.uint8) for _ in range(10)]
    for name, times in (("even", np.arange(10) / 4), ("gap", np.r_[0:5, 6:11] / 4)):
        writer = CameraMp4Writer(tmp_path / f"{name}.mp4", 4, (64, 48))
        for rgb, t in zip(frames, times, strict=True):
            writer.write(rgb, t)
        writer.commit()
        assert np.allclose(_stamps(tmp_path / f"{name}.mp4"), times, atol=1e-5)
    decoded = {}
    for name in ("even", "gap"):
        with av.open(str(tmp_path / f"{name}.mp4")) as c:
            decoded[name] = np.stack([f.to_ndarray(format="rgb24") for f in c.decode(video=0)])
    assert np.array_equal(decoded["even"], decoded["gap"])


@pytest.mark.parametrize("codec,suffix", [("mpeg4", "mkv"), ("libx264", "mp4")])
def test_a_reencode_that_keeps_the_stamps_tracks_at_the_true_times(footage, capsys, tmp_path,
                                                                  codec, suffix):
    """No sidecar: the container's times, the dropped frame's gap kept, so each pose is at the
    time its frame was taken (the truth a median ~1.5 mm off, as with the original)."""
    video = _reencode(footage / "drop.mp4", tmp_path / f"re.{suffix}", codec, "keep")
    code, _, err = _track(capsys, video, footage / "drop.toml", tmp_path / "trk")
    assert code == 0, err
    t = pq.read_table(tmp_path / "trk" / "poses.parquet").column("t").to_numpy()
    assert np.allclose(np.unique(t), _times(footage / "drop.times.csv"), atol=1e-3)
    error = _error_mm(tmp_path / "trk", footage / "run_drop")
    assert np.median(error) < 3 and np.percentile(error, 99) < 10
    manifest = json.loads((tmp_path / "trk" / "manifest.json").read_text())
    assert manifest["frame_times"] == "video"


def test_a_half_rate_reencode_is_refused_unless_fps_is_given(footage, capsys, tmp_path):
    video = _reencode(footage / "drop.mp4", tmp_path / "half.mp4", "libx264", "half")
    code, _, err = _track(capsys, video, footage / "drop.toml", tmp_path / "never")
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert "0.5 s apart" in err and "4 Hz" in err and "--fps" in err, err
    assert not (tmp_path / "never").exists()
    code, _, err = _track(capsys, video, footage / "drop.toml", tmp_path / "trk", "--fps", "2")
    assert code == 0, err
    t = pq.read_table(tmp_path / "trk" / "poses.parquet").column("t").to_numpy()
    assert np.allclose(np.unique(t), np.arange(12) / 2)


def test_an_evenly_restamped_video_disagrees_with_its_sidecar(footage, capsys, tmp_path):
    """Re-stamped evenly after a dropped frame, every later frame would be a period early; the
    sidecar says so, and the video is refused unless the user picks the times."""
    video = _reencode(footage / "drop.mp4", tmp_path / "even.mp4", "libx264", "even")
    sidecar = tmp_path / "even.times.csv"
    sidecar.write_text((footage / "drop.times.csv").read_text())
    code, _, err = _track(capsys, video, footage / "drop.toml", tmp_path / "never")
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert "disagree with even.times.csv: frame 10 is 2.500 s" in err and "2.750 s" in err, err
    assert f"--times {sidecar}" in err and not (tmp_path / "never").exists()
    code, _, err = _track(capsys, video, footage / "drop.toml", tmp_path / "trk", "--times",
                          str(sidecar))
    assert code == 0, err
    assert np.median(_error_mm(tmp_path / "trk", footage / "run_drop")) < 3


def test_an_evenly_restamped_video_without_its_sidecar_is_refused_by_the_motion(footage, capsys,
                                                                              tmp_path):
    """With no sidecar to say so, the robots' motion does: across a hidden gap every robot
    moving steadily goes twice its way (`hidden_drop`); the true times never raise it. Twenty
    seconds, so that the chain has got going."""
    from macrostate_mj.app.usecases.track import hidden_drop

    res = cli("simulate", "--scenario", str(footage / "drop.toml"), "--robots", "4",
              "--seconds", "20", "--seed", "3", "--track", "--camera-video",
              str(tmp_path / "long.mp4"), "--out", str(tmp_path / "run"))
    assert res.returncode == 0, res.stderr
    video = _reencode(tmp_path / "long.mp4", tmp_path / "even.mp4", "libx264", "even")
    code, _, err = _track(capsys, video, footage / "drop.toml", tmp_path / "never")
    lines = [ln for ln in err.strip().splitlines() if "tracking:" not in ln]   # no progress
    assert code == 2 and len(lines) == 1 and "Traceback" not in err, err
    assert "a dropped frame the times do not show" in err and "--times" in err
    assert not (tmp_path / "never").exists()
    run = pq.read_table(tmp_path / "run" / "poses.parquet").to_pandas()
    n = run.robot.nunique()
    tracked = run[["x_trk", "y_trk"]].to_numpy().reshape(-1, n, 2)
    detected = run.detected.to_numpy().reshape(-1, n)
    assert hidden_drop(tracked, detected, run.t.to_numpy()[::n]) is None


@pytest.mark.parametrize("case,words", [
    ("both", ["--times", "--fps", "not both"]),
    ("short", ["lists 3 frame times", "give the times file of this video"]),
    ("fps0", ["--fps"]),
])
def test_bad_times_flags_one_line_exit_2(footage, tmp_path, case, words):
    times = tmp_path / "t.csv"
    times.write_text("frame,t\n0,0.0\n1,0.25\n2,0.5\n")
    extra = {"both": ["--times", str(times), "--fps", "4"], "short": ["--times", str(times)],
             "fps0": ["--fps", "0"]}[case]
    res = cli("track", str(footage / "drop.mp4"), "--scenario", str(footage / "drop.toml"),
              "--robots", "4", "--out", str(tmp_path / "never"), *extra)
    assert_clean_error(res, *words)
    assert not (tmp_path / "never").exists()


@pytest.mark.parametrize("robots,words", [
    ("3", ["shows tags 0-3 (4 robots)", "--robots is 3", "give --robots 4"]),
    ("6", ["shows tags 0-3 (4 robots)", "none of 4-5", "give --robots 4"]),
])
def test_a_tag_team_the_video_contradicts_is_refused(footage, capsys, tmp_path, robots, words):
    code, _, err = _track(capsys, footage / "tags.mp4", footage / "tags.toml",
                          tmp_path / "never", robots=robots)
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1, err
    assert all(w in lines[0] for w in words), lines[0]
    assert not (tmp_path / "never").exists()


def test_the_tag_team_filmed_is_tracked(footage, capsys, tmp_path):
    code, out, err = _track(capsys, footage / "tags.mp4", footage / "tags.toml", tmp_path / "t")
    assert code == 0 and "T 100.0%" in out, err


@pytest.mark.parametrize("robots", ["3", "5"])
def test_a_colour_team_the_video_contradicts_is_refused(footage, capsys, tmp_path, robots):
    code, _, err = _track(capsys, footage / "drop.mp4", footage / "drop.toml",
                          tmp_path / "never", robots=robots)
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert "shows 4 colour markers" in err and "give --robots 4" in err, err
    assert not (tmp_path / "never").exists()


def test_a_robot_missed_in_many_frames_fails_naming_marker_and_cause(footage, capsys, tmp_path):
    """Every other frame washed out (no marker saturated enough): every robot under the
    limit, and the line names the marker kind and the likeliest cause."""
    tb = Fraction(1, 1000)
    video = tmp_path / "washed.mp4"
    with av.open(str(footage / "drop.mp4")) as inp, av.open(str(video), "w") as out:
        stream = out.add_stream("libx264", rate=4)
        stream.width, stream.height, stream.pix_fmt = 480, 360, "yuv444p"
        stream.codec_context.time_base = tb
        for k, f in enumerate(inp.decode(video=0)):
            rgb = f.to_ndarray(format="rgb24")
            if k % 2:
                rgb = (rgb * 0.3 + 150).astype(np.uint8)
            frame = av.VideoFrame.from_ndarray(rgb, format="rgb24")
            frame.pts, frame.time_base = round(f.time / tb), tb
            for packet in stream.encode(frame):
                out.mux(packet)
        for packet in stream.encode(None):
            out.mux(packet)
    code, _, err = _track(capsys, video, footage / "drop.toml", tmp_path / "trk")
    last = err.strip().splitlines()[-1]
    assert code == 1, err
    assert "colour marker (hue" in last and "likeliest cause blur or image quality" in last, last
    assert "poses kept in" in last and (tmp_path / "trk" / "poses.parquet").is_file()


@pytest.mark.parametrize("where,share,cause", [
    ((-1.1, 0.45), 0.2, "likeliest cause occlusion: in 100% of its misses"),
    ((1.2, 0.9), 0.2, "likeliest cause blur or a covered marker"),
    ((1.2, 0.9), 0.0, "likeliest cause team size or lab: its marker never shows (is --robots 3"),
])
def test_the_exit_1_line_names_the_likeliest_cause(where, share, cause):
    """Missed where it was last seen behind a box taller than its marker (from the camera):
    occlusion; in the open: blur or a covered marker; never: the team or the lab."""
    from pathlib import Path

    import mujoco

    from macrostate_mj.app.usecases.track import missed_line
    from macrostate_mj.chain.scenarios import get_scenario
    from macrostate_mj.chain.world import build_world
    from macrostate_mj.vision.trackers import tracker_for

    cfg = get_scenario(Path(__file__).parents[1] / "chain" / "obstacles.toml")
    world = build_world(cfg, 3)
    data = mujoco.MjData(world.model)
    mujoco.mj_forward(world.model, data)
    frames = 10
    tracked = np.zeros((frames, 3, 3))
    tracked[:, 2, :2] = where
    detected = np.ones((frames, 3), bool)
    detected[int(share * frames):, 2] = False
    line = missed_line(world, tracker_for(world, data),
                       {"tracked": tracked, "detected": detected}, {"T": share}, cfg)
    assert line.startswith(f"robot T's colour marker (hue 170 of 256, one of 3) detected in "
                           f"{share:.1%} of the frames (limit 90%; 1 of 3 robots under it)")
    assert cause in line and "\n" not in line, line


def test_sampled_frames_are_the_frames_asked_for_sought_or_decoded_on(tmp_path):
    """1200 frames (samples 80 apart: sought from key frames, x264 puts one every 250), each
    filled with its index: the frames handed to the team check are the ones spread evenly."""
    from macrostate_mj.app.usecases.track import probe, sample_frames
    from viz.video import CameraMp4Writer

    writer = CameraMp4Writer(tmp_path / "long.mp4", 4, (32, 16))
    for i in range(1200):
        rgb = np.zeros((16, 32, 3), np.uint8)
        rgb[..., 0], rgb[..., 1] = (i % 32) * 6, (i // 32) * 6
        writer.write(rgb, i / 4 + (i >= 600) * 0.25)          # a dropped frame at 600
    writer.commit()
    container = probe(tmp_path / "long.mp4")
    assert container.frames == 1200 and container.stamps[600] == pytest.approx(150.25)
    for count in (16, 3):
        got = sample_frames(tmp_path / "long.mp4", container, count)
        index = [int(np.round(f[..., 0].mean() / 6) + 32 * np.round(f[..., 1].mean() / 6))
                 for f in got]
        assert index == np.linspace(0, 1199, count).round().astype(int).tolist()
