"""Frames -> optical-flow samples in the OpticalFlows_HsAnts layout (SPEC §8).

The same code serves a real video file, a folder of frames and rendered frames held in memory:
every `every` seconds it takes m consecutive frame pairs `gap` seconds apart, computes dense flow,
encodes it the TSN way (clip to ±20 px, map linearly onto 0–255 so 128 means still) and resizes it
to 64 × 64. Sample i, sub-frame k is written as `flow_x_{i:05d}-{k}.jpg`, `flow_y_…` and `img_…`
(the RGB frame at the start of pair k).
"""

from __future__ import annotations

import math
import os
import re
import shutil
import tempfile
from collections.abc import Iterable, Iterator
from pathlib import Path

import cv2
import numpy as np

from macrostate_mj.core.errors import UserError
from macrostate_mj.formats.hsants import SAMPLE_KINDS, sample_file

BOUND = 20.0  # px: flows are clipped to ±BOUND before the linear map onto 0..255 (TSN convention)
SIZE = 64  # side of the written images
METHODS = ("dis", "farneback", "tvl1")
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".ppm")
JPEG_QUALITY = 95
MEDIUM_MAX_PX = 256 * 256  # largest frame DIS runs with its MEDIUM preset (dis_preset)

_TVL1_HINT = ("TV-L1 needs OpenCV's contrib build: pip uninstall opencv-python-headless && "
              "pip install opencv-contrib-python-headless (replace it, never install both), "
              "or use --method dis")


def encode_flow(flow: np.ndarray, size: int = SIZE) -> tuple[np.ndarray, np.ndarray]:
    """Encode an H×W×2 flow (px) as two size×size uint8 images, 128 = still, ±BOUND px = 0/255."""
    # v = 127.5 + flow·255/40, rounded half-to-even and saturated at 0/255 (= clipping at ±BOUND)
    flow = np.ascontiguousarray(flow, dtype=np.float32)
    img = cv2.addWeighted(flow, 255.0 / (2 * BOUND), flow, 0.0, 127.5, dtype=cv2.CV_8U)
    if img.shape[:2] != (size, size):
        img = cv2.resize(img, (size, size), interpolation=cv2.INTER_AREA)
    return img[..., 0], img[..., 1]


def decode_flow(img: np.ndarray) -> np.ndarray:
    """Inverse of the linear map of `encode_flow`: uint8 image -> flow in px (clipped at ±BOUND)."""
    return img.astype(np.float32) * (2 * BOUND / 255.0) - BOUND


def dis_preset(shape: tuple[int, ...]) -> int:
    """MEDIUM up to 256² (the simulated colony's frames); ULTRAFAST on larger ones, where MEDIUM
    costs ~10× more per pair. At 64² MEDIUM is both faster and more exact; at 256² it costs 22 ms
    per pair against 1.9 ms, but ULTRAFAST smears flow over half the nest: the flow-magnitude peak
    of a crowded simulated D+2 then lands in a duel box less often than chance (.19 vs .29),
    with MEDIUM more often (.37)."""
    small = shape[0] * shape[1] <= MEDIUM_MAX_PX
    return cv2.DISOPTICAL_FLOW_PRESET_MEDIUM if small else cv2.DISOPTICAL_FLOW_PRESET_ULTRAFAST


class FlowComputer:
    """Dense flow between two grey frames; keeps one DIS object per image size (SPEC §9)."""

    def __init__(self, method: str = "dis") -> None:
        if method not in METHODS:
            raise UserError(f"unknown flow method {method!r}; choose from {', '.join(METHODS)}")
        if method == "tvl1" and not hasattr(cv2, "optflow"):
            raise UserError(f"cv2.optflow is missing in OpenCV {cv2.__version__}. {_TVL1_HINT}")
        self.method = method
        self._dis: dict[tuple[int, int], cv2.DISOpticalFlow] = {}
        self._tvl1 = cv2.optflow.DualTVL1OpticalFlow_create() if method == "tvl1" else None

    def __call__(self, prev: np.ndarray, nxt: np.ndarray) -> np.ndarray:
        if self.method == "dis":
            dis = self._dis.get(prev.shape)
            if dis is None:
                dis = self._dis[prev.shape] = cv2.DISOpticalFlow_create(dis_preset(prev.shape))
            return dis.calc(prev, nxt, None)
        if self.method == "farneback":
            return cv2.calcOpticalFlowFarneback(prev, nxt, None, 0.5, 3, 15, 3, 5, 1.2, 0)
        return self._tvl1.calc(prev, nxt, None)


def sample_frame_indices(i: int, fps: float, every: float, gap: float, m: int) -> list[int]:
    """Frame indices of sample i: m + 1 frames `gap` s apart starting at i·every s."""
    return [int(math.floor((i * every + j * gap) * fps + 0.5 + 1e-9)) for j in range(m + 1)]


def extract_flow_samples(frames: Iterable[np.ndarray], fps: float, out_dir: Path, *, every: float,
                         gap: float = 0.5, m: int = 4, method: str = "dis",
                         label: str | None = None, start_id: int = 0,
                         crop: tuple[int, int, int, int] | None = None) -> list[int]:
    """Turn a stream of H×W×3 uint8 RGB frames into flow samples; return the written sample ids.

    Files appear only when the whole stream succeeded (staged in a hidden sibling folder, then
    moved), so a bad frame midway leaves nothing half-written. A tail too short for a complete
    sample is dropped.
    """
    _check_params(fps, every, gap, m, start_id)
    computer = FlowComputer(method)
    target = Path(out_dir) / label if label else Path(out_dir)
    target.mkdir(parents=True, exist_ok=True)
    stage = Path(tempfile.mkdtemp(prefix=".flow-stage-", dir=target))
    try:
        ids = _extract(frames, fps, stage, every, gap, m, computer, start_id, crop)
        for name in sorted(os.listdir(stage)):
            os.replace(stage / name, target / name)
    finally:
        shutil.rmtree(stage, ignore_errors=True)
    return ids


def _check_params(fps: float, every: float, gap: float, m: int, start_id: int) -> None:
    if not (fps > 0 and math.isfinite(fps)):
        raise UserError(f"frame rate fps {fps} is not positive; pass the video's rate", "fps")
    if not every > 0 or not gap > 0:
        raise UserError(f"every ({every}) and gap ({gap}) must be positive seconds",
                        "every" if not every > 0 else "gap")
    if m < 1:
        raise UserError(f"m {m} must be at least 1", "m")
    if start_id < 0:
        raise UserError(f"start_id {start_id} must be >= 0", "start_id")
    if round(gap * fps) < 1:
        raise UserError(f"gap {gap} s is under one frame at {fps:g} fps; use a larger gap",
                        "gap")


def _extract(frames: Iterable[np.ndarray], fps: float, stage: Path, every: float, gap: float,
             m: int, computer: FlowComputer, start_id: int,
             crop: tuple[int, int, int, int] | None) -> list[int]:
    """Stream frames once, keeping only those that an open sample still needs."""
    written: list[int] = []
    open_samples: dict[int, dict[int, np.ndarray]] = {}  # sample -> frame index -> grey/RGB
    next_sample, shape = 0, None
    for n, frame in enumerate(frames):
        if shape is None:
            shape = frame.shape
            _check_frame(frame, n, crop)
        elif frame.shape != shape:
            raise UserError(f"frame {n} is {frame.shape[1]}x{frame.shape[0]} but frame 0 is "
                            f"{shape[1]}x{shape[0]}; all frames must have the same size")
        while sample_frame_indices(next_sample, fps, every, gap, m)[0] <= n:
            open_samples[next_sample] = {}
            next_sample += 1
        for s in list(open_samples):
            idx = sample_frame_indices(s, fps, every, gap, m)
            if n in idx:
                open_samples[s][n] = _crop(frame, crop)
            if n == idx[-1]:
                got = open_samples.pop(s)
                _write_sample(stage, start_id + s, [got[j] for j in idx], computer)
                written.append(start_id + s)
    if shape is None:
        raise UserError("the video or frame folder holds no frames; check the input")
    if not written:
        raise UserError(f"the input ({n + 1} frames at {fps:g} fps) is too short for one sample of "
                        f"{m} pairs {gap} s apart; lower m or gap, or use a longer input")
    return written


def _check_frame(frame: np.ndarray, n: int, crop: tuple[int, int, int, int] | None) -> None:
    if frame.ndim != 3 or frame.shape[2] != 3 or frame.dtype != np.uint8:
        raise UserError(f"frame {n} is {frame.shape} {frame.dtype}; expected HxWx3 uint8 RGB")
    if crop is not None:
        x, y, w, h = crop
        if w <= 0 or h <= 0 or x < 0 or y < 0 or x + w > frame.shape[1] or y + h > frame.shape[0]:
            raise UserError(f"--crop {x},{y},{w},{h} does not fit the {frame.shape[1]}x"
                            f"{frame.shape[0]} frames; give x,y,w,h inside the frame")


def _crop(frame: np.ndarray, crop: tuple[int, int, int, int] | None) -> np.ndarray:
    if crop is None:
        return frame
    x, y, w, h = crop
    return frame[y:y + h, x:x + w]


def _write_sample(stage: Path, sid: int, frames: list[np.ndarray], computer: FlowComputer) -> None:
    grey = [cv2.cvtColor(f, cv2.COLOR_RGB2GRAY) for f in frames]
    for k in range(len(frames) - 1):
        fx, fy = encode_flow(computer(grey[k], grey[k + 1]))
        img = cv2.resize(frames[k], (SIZE, SIZE), interpolation=cv2.INTER_AREA)
        for kind, arr in zip(SAMPLE_KINDS, (fx, fy, cv2.cvtColor(img, cv2.COLOR_RGB2BGR)),
                             strict=True):
            ok, buf = cv2.imencode(".jpg", arr, [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
            if not ok:
                raise UserError(f"could not encode {sample_file(kind, sid, k)}")
            (stage / sample_file(kind, sid, k)).write_bytes(buf.tobytes())


def read_video_frames(path: str | os.PathLike, fps: float | None = None,
                      ) -> tuple[Iterator[np.ndarray], float]:
    """Open any OpenCV-readable video; frames come out as RGB uint8. `fps` overrides the header."""
    path = Path(path)
    if not path.is_file():
        raise UserError(f"video {path} does not exist; check --video")
    cap = cv2.VideoCapture(str(path))
    ok, first = cap.read() if cap.isOpened() else (False, None)
    if not ok or first is None:
        cap.release()
        raise UserError(f"cannot read any frame from video {path} (empty or unreadable); "
                        "check the file or convert it with ffmpeg")
    rate = fps if fps else float(cap.get(cv2.CAP_PROP_FPS) or 0.0)
    if not (rate > 0 and math.isfinite(rate)):
        cap.release()
        raise UserError(f"video {path} does not state its frame rate; pass --fps")

    def gen() -> Iterator[np.ndarray]:
        try:
            frame = first
            while frame is not None:
                yield cv2.cvtColor(frame, cv2.COLOR_BGR2RGB)
                ok, frame = cap.read()
                frame = frame if ok else None
        finally:
            cap.release()

    return gen(), rate


def _natural_key(p: Path) -> list[object]:
    return [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", p.name)]


def read_frame_folder(path: str | os.PathLike, fps: float) -> tuple[Iterator[np.ndarray], float]:
    """Frames of a folder of images in natural name order (frame2 before frame10), as RGB."""
    path = Path(path)
    if not path.is_dir():
        raise UserError(f"frames folder {path} does not exist; check --frames")
    files = sorted((p for p in path.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES),
                   key=_natural_key)
    if not files:
        raise UserError(f"frames folder {path} holds no images ({', '.join(IMAGE_SUFFIXES)})")
    if not (fps and fps > 0):
        raise UserError("a frames folder has no frame rate; pass --fps")

    def gen() -> Iterator[np.ndarray]:
        size = None
        for f in files:
            img = cv2.imread(str(f), cv2.IMREAD_COLOR)
            if img is None:
                raise UserError(f"cannot read frame {f}; remove or replace it")
            if size is None:
                size = img.shape
            elif img.shape != size:
                raise UserError(f"frames folder has mixed sizes: {f.name} is {img.shape[1]}x"
                                f"{img.shape[0]}, {files[0].name} is {size[1]}x{size[0]}; "
                                "resize them to one size")
            yield cv2.cvtColor(img, cv2.COLOR_BGR2RGB)

    return gen(), float(fps)
