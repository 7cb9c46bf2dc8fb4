"""Reader for the OpticalFlows_HsAnts layout (the published dataset of §4.7), real or simulated.

`Stable/` and `Unstable/` hold, per sample id i and sub-frame k, `flow_x_i-k.jpg`, `flow_y_i-k.jpg`
(64 × 64 grey, 128 = still) and `img_i-k.jpg`; `split{1,2,3}/{train,test}.csv` list stable samples
as `Stable/00000`. Inputs stack the first m sub-frames as channels (x0, y0, x1, y1, …), channels
first for torch: N × 2m × 64 × 64 float32 in [−1, 1].

Time bins. The dissertation (Fig 4.8) bins unstable samples by their 0-based position in the
full unstable list (11,984 samples, ids 1333–13316). Position is computed as id − n_stable (the
first unstable id of a complete dataset), so a dataset that ships only a subset of unstable
samples, like the 48 smoke samples here, still puts each sample in its true day bin. A dataset
with another timeline (the simulated colony) may say its own bins in `bins.json`:
{"D+1": [first_id, end_id), …} in ids.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass, field, replace
from pathlib import Path

import cv2
import numpy as np

from macrostate_mj.core.errors import UserError

LABELS = ("Stable", "Unstable")
SPLITS = (1, 2, 3)
# (name, start, end) over the 0-based position in the full unstable list (SPEC §8).
SPEC_BINS: tuple[tuple[str, int, int], ...] = (
    ("D+1", 0, 666), ("D+2", 666, 1333), ("D+3-6", 1333, 4000), ("D+7-10", 4000, 6666),
    ("D+11-14", 6666, 9333), ("D+15-18", 9333, 11984))
BIN_NAMES = tuple(b[0] for b in SPEC_BINS)
# The one home of the sample file names: `{kind}_{id:05d}-{k}.jpg`, kind flow_x, flow_y or img.
SAMPLE_KINDS = ("flow_x", "flow_y", "img")
SAMPLE_NAME = re.compile(r"^flow_x_(\d+)-(\d+)\.jpg$")


def sample_file(kind: str, sid: int, k: int) -> str:
    """File name of sub-frame k of sample `sid` (kind flow_x, flow_y or img)."""
    return f"{kind}_{sid:05d}-{k}.jpg"


@dataclass(frozen=True)
class AntFlowData:
    """What a dataset folder holds: sample ids per label and sub-frames per sample."""

    root: Path
    stable_ids: tuple[int, ...]
    unstable_ids: tuple[int, ...]
    subframes: int  # sub-frames every sample has (the smallest count over samples)
    bins: dict[str, tuple[int, int]] = field(default_factory=dict)  # name -> [first, end) ids
    unstable_dir: Path | None = None  # Unstable/ held apart (a dev set); default root/Unstable

    def split(self, k: int) -> tuple[list[int], list[int]]:
        """Stable (train, test) ids of split k."""
        return read_split(self.root, k)

    def load(self, label: str, ids: list[int] | tuple[int, ...], m: int) -> np.ndarray:
        """Stack samples of one label into N × 2m × 64 × 64 float32 in [−1, 1]."""
        if m < 1 or m > self.subframes:
            raise UserError(f"m {m} needs {m} sub-frames per sample but {self.root} has "
                            f"{self.subframes}; choose m in 1..{self.subframes}", "m")
        folder = self.unstable_dir if label == "Unstable" and self.unstable_dir else (
            self.root / label)
        return load_samples(folder, ids, m)

    def with_unstable(self, folder: str | Path) -> AntFlowData:
        """The same stable samples, splits and bins, with the unstable samples of `folder` (a
        dev set such as OpticalFlows_HsAnts-dev/Unstable, whose ids are the full colony's)."""
        ids, subframes = _index(Path(folder))
        return replace(self, unstable_ids=ids, subframes=min(self.subframes, subframes),
                       unstable_dir=Path(folder))

    def time_bin(self, ids: list[int] | tuple[int, ...]) -> list[str | None]:
        """Day bin of each unstable id (None when it falls outside every bin)."""
        out: list[str | None] = []
        for i in ids:
            out.append(next((n for n, (a, b) in self.bins.items() if a <= i < b), None))
        return out


def open_dataset(root: str | Path) -> AntFlowData:
    """Index a dataset folder; fail with one line if its layout is not the expected one."""
    root = Path(root)
    if not root.is_dir():
        raise UserError(f"dataset folder {root} does not exist; check the path", "data")
    ids, subs = {}, []
    for label in LABELS:
        folder = root / label
        if not folder.is_dir():
            raise UserError(f"dataset {root} has no {label}/ folder; give the folder holding "
                            "Stable/, Unstable/ and split1..3/", "data")
        ids[label], sub = _index(folder)
        subs.append(sub)
    return AntFlowData(root, ids["Stable"], ids["Unstable"], min(subs),
                       _read_bins(root, len(ids["Stable"])))


def _index(folder: Path) -> tuple[tuple[int, ...], int]:
    """Sample ids in a folder of samples, and the sub-frames every one of them has."""
    counts: dict[int, int] = {}
    for name in (p.name for p in folder.iterdir()):
        hit = SAMPLE_NAME.match(name)
        if hit:
            counts[int(hit.group(1))] = counts.get(int(hit.group(1)), 0) + 1
    if not counts:
        raise UserError(f"{folder} holds no flow_x_*.jpg samples; extract flows first")
    return tuple(sorted(counts)), min(counts.values())


def _read_bins(root: Path, n_stable: int) -> dict[str, tuple[int, int]]:
    path = root / "bins.json"
    if not path.is_file():
        return {name: (n_stable + a, n_stable + b) for name, a, b in SPEC_BINS}
    try:
        raw = json.loads(path.read_text())
        return {str(k): (int(v[0]), int(v[1])) for k, v in raw.items()}
    except (ValueError, TypeError, IndexError, AttributeError) as err:
        raise UserError(f"{path} is not a {{bin: [first_id, end_id]}} object ({err}); fix or "
                        "delete it") from None


def read_split(root: str | Path, k: int) -> tuple[list[int], list[int]]:
    """Stable (train, test) ids listed in `split{k}/{train,test}.csv`."""
    root = Path(root)
    out = []
    for part in ("train", "test"):
        path = root / f"split{k}" / f"{part}.csv"
        if not path.is_file():
            raise UserError(f"dataset {root} lacks split{k}/{part}.csv; use split 1..3 on a "
                            "dataset that has its splits", "split")
        ids = []
        for n, line in enumerate(path.read_text().splitlines(), 1):
            line = line.strip()
            if not line:
                continue
            hit = re.fullmatch(r"Stable/(\d+)", line)
            if not hit:
                raise UserError(f"{path} line {n} is {line!r}, expected Stable/NNNNN; fix the file")
            ids.append(int(hit.group(1)))
        if not ids:
            raise UserError(f"{path} lists no samples; fix the split file")
        out.append(ids)
    return out[0], out[1]


def read_jpeg(path: Path, colour: bool = False) -> np.ndarray:
    """Decode one 64 × 64 JPEG, refusing truncated files that OpenCV would half-decode."""
    try:
        raw = path.read_bytes()
    except OSError:
        raise UserError(f"missing or unreadable image {path}; restore the dataset") from None
    img = None
    if raw[:2] == b"\xff\xd8" and raw.rstrip(b"\x00")[-2:] == b"\xff\xd9":
        flag = cv2.IMREAD_COLOR if colour else cv2.IMREAD_GRAYSCALE
        img = cv2.imdecode(np.frombuffer(raw, np.uint8), flag)
    if img is None:
        raise UserError(f"corrupt JPEG {path}; re-extract or remove that sample")
    return cv2.cvtColor(img, cv2.COLOR_BGR2RGB) if colour else img


def load_samples(folder: Path, ids: list[int] | tuple[int, ...], m: int) -> np.ndarray:
    """N × 2m × 64 × 64 float32 in [−1, 1] from the first m sub-frames of each sample."""
    out = np.empty((len(ids), 2 * m, 64, 64), np.float32)
    for n, i in enumerate(ids):
        for k in range(m):
            for c, axis in enumerate(("x", "y")):
                path = folder / sample_file(f"flow_{axis}", i, k)
                img = read_jpeg(path)
                if img.shape != (64, 64):
                    raise UserError(f"{path} is {img.shape[1]}x{img.shape[0]}, expected 64x64; "
                                    "re-extract it")
                out[n, 2 * k + c] = img
    return out / np.float32(127.5) - np.float32(1.0)


def load_images(folder: Path, ids: list[int] | tuple[int, ...], m: int) -> np.ndarray:
    """N × m × 64 × 64 × 3 uint8 RGB `img` frames (for overlays)."""
    return np.stack([np.stack([read_jpeg(folder / sample_file("img", i, k), colour=True)
                               for k in range(m)]) for i in ids])
