"""Flow pipeline: TSN encoding, a known shift end to end, video = frames, bad input."""

import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from macrostate_mj.core.errors import UserError
from macrostate_mj.vision import flow

REPO = Path(__file__).resolve().parents[2]


def _texture(h: int, w: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    grey = cv2.GaussianBlur((rng.random((h, w)) * 255).astype(np.uint8), (0, 0), 2.0)
    return np.dstack([grey, grey, grey // 2 + 60])


def _shifting_frames(n: int, dx: int, size: int = 96) -> list[np.ndarray]:
    """Frame t shows the texture moved right by dx·t px (a window sliding left over it)."""
    big = _texture(size, size + dx * n + 8)
    x0 = dx * n
    return [np.ascontiguousarray(big[:, x0 - dx * t: x0 - dx * t + size]) for t in range(n)]


def test_encoding_is_tsn_linear_map():
    f = np.zeros((64, 64, 2), np.float32)
    f[..., 0], f[:32, :, 1], f[32:, :, 1] = 3.0, 25.0, -25.0
    fx, fy = flow.encode_flow(f)
    assert fx[0, 0] == round(127.5 + 3 * 255 / 40)  # 146.6 -> 147
    assert fy[0, 0] == 255 and fy[-1, 0] == 0  # clipped at ±20 px
    assert flow.encode_flow(np.zeros((8, 8, 2), np.float32))[0][0, 0] == 128  # still = 128
    assert abs(flow.decode_flow(fx)[0, 0] - 3.0) < 40 / 255


TVL1 = pytest.param("tvl1", marks=pytest.mark.skipif(
    not hasattr(cv2, "optflow"), reason="TV-L1 needs opencv-contrib-python-headless (docs)"))


@pytest.mark.parametrize("method", ["dis", "farneback", TVL1])
def test_known_shift_is_recovered(tmp_path, method):
    frames = _shifting_frames(5, dx=3)
    ids = flow.extract_flow_samples(frames, fps=2.0, out_dir=tmp_path, every=1.0, gap=0.5, m=2,
                                    method=method, label="Stable", start_id=7)
    assert ids == [7, 8]  # samples at frames 0-2 and 2-4
    folder = tmp_path / "Stable"
    for k in range(2):
        fx = flow.decode_flow(cv2.imread(str(folder / f"flow_x_00007-{k}.jpg"), 0))
        fy = flow.decode_flow(cv2.imread(str(folder / f"flow_y_00007-{k}.jpg"), 0))
        assert fx.shape == (64, 64)
        assert abs(np.median(fx[16:48, 16:48]) - 3.0) < 0.3
        assert abs(np.median(fy[16:48, 16:48])) < 0.3
    img = cv2.imread(str(folder / "img_00008-1.jpg"), cv2.IMREAD_COLOR)
    assert img.shape == (64, 64, 3)
    assert not list(folder.glob(".flow-stage-*"))  # staging folder cleaned up


def test_frames_folder_and_video_match_in_memory(tmp_path):
    frames = _shifting_frames(6, dx=2)
    ref = flow.extract_flow_samples(frames, 4.0, tmp_path / "mem", every=0.5, gap=0.25, m=1)
    folder = tmp_path / "frames"
    folder.mkdir()
    for i, f in enumerate(frames):  # frame2 must sort before frame10: natural order
        cv2.imwrite(str(folder / f"frame{i}.png"), cv2.cvtColor(f, cv2.COLOR_RGB2BGR))
    it, fps = flow.read_frame_folder(folder, 4.0)
    assert flow.extract_flow_samples(it, fps, tmp_path / "png", every=0.5, gap=0.25, m=1) == ref
    for name in (p.name for p in (tmp_path / "mem").iterdir()):
        assert (tmp_path / "png" / name).read_bytes() == (tmp_path / "mem" / name).read_bytes()

    video = tmp_path / "clip.avi"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"MJPG"), 4.0, (96, 96))
    for f in frames:
        writer.write(cv2.cvtColor(f, cv2.COLOR_RGB2BGR))
    writer.release()
    it, fps = flow.read_video_frames(video)
    assert fps == pytest.approx(4.0)
    assert flow.extract_flow_samples(it, fps, tmp_path / "vid", every=0.5, gap=0.25, m=1) == ref
    fx = flow.decode_flow(cv2.imread(str(tmp_path / "vid" / "flow_x_00000-0.jpg"), 0))
    assert abs(np.median(fx[16:48, 16:48]) - 2.0) < 0.4


def test_bad_inputs_are_user_errors(tmp_path):
    empty = tmp_path / "empty.mp4"
    empty.write_bytes(b"")
    with pytest.raises(UserError, match="cannot read"):
        flow.read_video_frames(empty)
    frames = _shifting_frames(3, dx=1)
    with pytest.raises(UserError, match="too short"):
        flow.extract_flow_samples(frames, 2.0, tmp_path / "o", every=1.0, m=4)
    with pytest.raises(UserError, match="crop"):
        flow.extract_flow_samples(frames, 2.0, tmp_path / "o", every=1.0, m=1, crop=(0, 0, 500, 9))
    if not hasattr(cv2, "optflow"):
        with pytest.raises(UserError, match="opencv-contrib-python-headless"):
            flow.FlowComputer("tvl1")
    assert not list((tmp_path / "o").glob("flow_*"))


def test_cli_mixed_frame_sizes_exit_2_one_line_nothing_written(tmp_path):
    folder = tmp_path / "frames"
    folder.mkdir()
    for i, size in enumerate((64, 64, 64, 80)):
        cv2.imwrite(str(folder / f"{i:03d}.png"), _texture(size, size, i))
    out = tmp_path / "out"
    out.mkdir()
    proc = subprocess.run([sys.executable, "-m", "macrostate_mj.app.cli", "flow", "--frames",
                           str(folder), "--out", str(out), "--fps", "2", "--every", "0.5",
                           "--m", "1"], capture_output=True, text=True, cwd=REPO)
    assert proc.returncode == 2
    assert proc.stderr.strip().count("\n") == 0 and "Traceback" not in proc.stderr
    assert "mixed sizes" in proc.stderr and "003.png" in proc.stderr
    assert not [p for p in out.rglob("*") if p.is_file()]


def test_cli_writes_layout_and_refuses_to_clobber(tmp_path):
    folder = tmp_path / "frames"
    folder.mkdir()
    for i, f in enumerate(_shifting_frames(6, dx=2)):
        cv2.imwrite(str(folder / f"f{i}.png"), cv2.cvtColor(f, cv2.COLOR_RGB2BGR))
    out = tmp_path / "ds"
    args = [sys.executable, "-m", "macrostate_mj.app.cli", "flow", "--frames", str(folder), "--out",
            str(out), "--fps", "4", "--every", "0.25", "--gap", "0.25", "--m", "1", "--label",
            "Unstable", "--start-id", "1333", "--crop", "8,8,80,80"]
    proc = subprocess.run(args, capture_output=True, text=True, cwd=REPO)
    assert proc.returncode == 0, proc.stderr
    names = {p.name for p in (out / "Unstable").iterdir()}
    assert {"flow_x_01333-0.jpg", "flow_y_01337-0.jpg", "img_01337-0.jpg", "manifest.json"} <= names
    assert "flow_x_01338-0.jpg" not in names  # 6 frames, pairs (0,1)..(4,5): 5 samples
    again = subprocess.run(args, capture_output=True, text=True, cwd=REPO)
    assert again.returncode == 2 and "already exists" in again.stderr
