"""`ants simulate` as a library call: colony days → frames/video → flows in the HsAnts layout.

Output folder (everything staged in a hidden sibling folder and moved into place at the end, so a
failed run leaves no half-written product):

- `flows/Stable/…`, `flows/Unstable/…`: flow samples written by `macrostate_mj.vision.flow`, ids in
  global temporal order (stable days first), exactly like OpticalFlows_HsAnts;
  `flows/split{1,2,3}/{train,test}.csv` (80/20 of the stable ids, three seeded splits);
  `flows/boxes.csv` (`sample_id,k,x,y,w,h`: duel/bite boxes in 64 × 64 sample coordinates, the
  union over the two frames of pair k, for a Grad-CAM pointing game); `flows/samples.csv`;
  `flows/bins.json` (the Fig 4.8 day bins as [first_id, end_id) for macrostate_mj.formats.hsants).
- `labels.csv`: one row per sample (Stable before the removal, Unstable after) with its day.
- `boxes.csv`: per frame, each duel or bite with both ants and its pixel box.
- `video/D±N.mp4` (`--video`), `frames/D±N/000000.jpg` (`--frames`), `manifest.json`.
"""

from __future__ import annotations

import csv
import math
import os
import shutil
import tempfile
import time
from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from macrostate_mj.colony.colony_sim import Colony, ColonyConfig, aggression, day_name, parse_days
from macrostate_mj.core import draw
from macrostate_mj.core.checks import check_seed
from macrostate_mj.core.errors import UserError
from macrostate_mj.core.run import Run

PRODUCTS = ["flows", "labels.csv", "boxes.csv", "video", "frames"]
SAMPLE = 64  # side of the flow images (macrostate_mj.vision.flow.SIZE)


@dataclass(frozen=True)
class ColonyRequest:
    """Everything `ants simulate` was asked for."""

    out: Path
    ants: int = 55
    days: str = "D-2..D+18"
    seconds_per_day: float = 60.0
    fps: float = 15.0
    size: int = 256
    seed: int = 0
    prey: int = 0
    video: bool = False
    frames: bool = False
    every: float = 2.0
    gap: float = 0.5
    m: int = 4
    method: str = "dis"
    overwrite: bool = False


def validate(req: ColonyRequest) -> list[int]:
    """Check every argument before any work; return the days to simulate."""
    days = parse_days(req.days)
    if not 1 <= req.ants <= 80:
        raise UserError(f"--ants {req.ants} is outside 1..80 (the nest holds about 80 at most)")
    if not 0 <= req.prey <= 10:
        raise UserError(f"--prey {req.prey} is outside 0..10")
    if not (math.isfinite(req.fps) and 1 <= req.fps <= 60):
        raise UserError(f"--fps {req.fps} is outside 1..60")
    if not 32 <= req.size <= 1024 or req.size % 8:
        raise UserError(f"--size {req.size} must be a multiple of 8 in 32..1024 px (video codecs "
                        "want multiples of 8; the offscreen buffer is 1024)")
    check_seed(req.seed)
    if not (math.isfinite(req.every) and req.every > 0 and math.isfinite(req.gap) and req.gap > 0):
        raise UserError(f"--every ({req.every}) and --gap ({req.gap}) must be positive seconds")
    if req.m < 1:
        raise UserError(f"--m {req.m} must be at least 1")
    if round(req.gap * req.fps) < 1:
        raise UserError(f"--gap {req.gap} s is under one frame at {req.fps:g} fps; raise --gap")
    if not (math.isfinite(req.seconds_per_day) and req.seconds_per_day > 0):
        raise UserError(f"--seconds-per-day {req.seconds_per_day} must be positive")
    need = req.m * req.gap + 1.0 / req.fps
    if req.seconds_per_day < need:
        raise UserError(f"--seconds-per-day {req.seconds_per_day} is too short for one sample of "
                        f"{req.m} pairs {req.gap} s apart; use at least {need:.2f}")
    from macrostate_mj.vision.flow import FlowComputer

    FlowComputer(req.method)  # unknown method or missing TV-L1 fails here, before any work
    return days


def stable_splits(ids: list[int], seed: int, n_splits: int = 3, test_share: float = 0.2,
                  ) -> list[tuple[list[int], list[int]]]:
    """Seeded (train, test) partitions of the stable ids, 80/20 like the real set (1067/266)."""
    out = []
    for k in range(1, n_splits + 1):
        perm = np.random.default_rng([seed, k]).permutation(len(ids))
        n_test = max(1, int(test_share * len(ids)))
        test = sorted(ids[i] for i in perm[:n_test])
        train = sorted(ids[i] for i in perm[n_test:])
        out.append((train, test))
    return out


def sample_boxes(sid: int, idx: list[int], events: dict[int, list], scale: float) -> list[list]:
    """Rows (sample_id, k, x, y, w, h) in sample pixels: each duel/bite in pair k's first frame,
    unioned with the same pair's box in the pair's second frame (the flow spans both)."""
    rows = []
    for k in range(len(idx) - 1):
        later = {(kind, a, b): box for kind, a, b, box in events.get(idx[k + 1], [])}
        for kind, a, b, (x, y, w, h) in events.get(idx[k], []):
            x1, y1 = x + w, y + h
            if (kind, a, b) in later:
                bx, by, bw, bh = later[(kind, a, b)]
                x, y, x1, y1 = min(x, bx), min(y, by), max(x1, bx + bw), max(y1, by + bh)
            rows.append([sid, k, *(round(v * scale, 2) for v in (x, y, x1 - x, y1 - y))])
    return rows


BINS = (("D+1", 1, 1), ("D+2", 2, 2), ("D+3-6", 3, 6), ("D+7-10", 7, 10), ("D+11-14", 11, 14),
        ("D+15-18", 15, 18))  # the time bins of SPEC §8 / Fig 4.8, in days


def day_bins(labels: list[list]) -> dict[str, list[int]]:
    """{bin: [first_id, end_id)} over the unstable samples present (the `bins.json` that
    macrostate_mj.formats.hsants reads in place of the real set's fixed index bins)."""
    out = {}
    for name, lo, hi in BINS:
        ids = [r[0] for r in labels if r[2] == "Unstable" and lo <= int(r[3][1:]) <= hi]
        if ids:
            out[name] = [min(ids), max(ids) + 1]
    return out


def _day_frames(colony: Colony, req: ColonyRequest, day: int, render: set[int] | None,
                renderer, events: dict[int, list], frame_rows: list, writer,
                frame_dir: Path | None, advance: Callable[[float], None] | None,
                ) -> Iterator[np.ndarray]:
    """Frames of one day for the flow extractor; records events and writes video/frames."""
    import cv2

    last = None
    for k, (frame, evs) in enumerate(colony.run(req.seconds_per_day, render, renderer)):
        # an unrendered frame is never a sample frame: the last rendered one fills its slot
        last = frame if frame is not None else last
        events[k] = evs
        for kind, a, b, xywh in evs:
            frame_rows.append([day_name(day), k, round(k / req.fps, 4), kind, a, b,
                               *(round(v, 2) for v in xywh)])
        if writer is not None or frame_dir is not None:
            bgr = cv2.cvtColor(last, cv2.COLOR_RGB2BGR)
            if frame_dir is not None:     # the raw frames: input for `flow --frames`
                cv2.imwrite(str(frame_dir / f"{k:06d}.jpg"), bgr)
            if writer is not None:        # the video is for people: day, clock, true events
                writer.write_bgr(_annotated(bgr, day, k / req.fps, evs))
        if advance is not None and k % max(1, int(req.fps)) == 0:
            advance(k / req.fps)
        yield last


EVENT_COLOURS = {"duel": (0, 140, 255), "bite": (0, 0, 230)}   # BGR: orange, red


def _annotated(bgr: np.ndarray, day: int, t: float, evs: list) -> np.ndarray:
    """A copy of the frame with the day (and its label), the clock and the ground-truth duel
    and bite boxes of this frame, as boxes.csv lists them."""
    out = bgr.copy()
    scale = 0.35 if out.shape[1] < 400 else 0.5
    state = "stable" if day < 0 else "unstable"
    draw.label(out, f"{day_name(day)} ({state})  t = {t:6.2f} s", (4, int(28 * scale)), scale)
    for kind, a, b, xywh in evs:
        draw.box(out, xywh, EVENT_COLOURS[kind], f"{kind} {a}-{b}")
    return out


def _write_csv(path: Path, header: list[str] | None, rows: list) -> None:
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        if header:
            w.writerow(header)
        w.writerows(rows)


def simulate_colony(req: ColonyRequest, advance: Callable[[float], None] | None = None,
                    ) -> dict[str, Path]:
    """Run the colony over its days and write all products; return what was written."""
    days = validate(req)
    config = {k: v for k, v in asdict(req).items() if k not in ("out", "overwrite")}
    with Run(req.out, "ants simulate", config, req.seed, PRODUCTS, req.overwrite) as run:
        return _simulate_days(req, days, run, advance)


def _simulate_days(req: ColonyRequest, days: list[float], run: Run,
                   advance: Callable[[float], None] | None) -> dict[str, Path]:
    import mujoco

    from macrostate_mj.core.io import Mp4Writer, write_json_atomic
    from macrostate_mj.vision.flow import extract_flow_samples, sample_frame_indices

    out = Path(req.out)
    stage = Path(tempfile.mkdtemp(prefix=".colony-stage-", dir=out))
    cfg = ColonyConfig(n_ants=req.ants, n_prey=req.prey, fps=req.fps, size=req.size,
                       seed=req.seed)
    labels, frame_rows, flow_boxes, stable_ids = [], [], [], []
    timings: dict[str, float] = {}
    renderer = None
    try:
        t0 = time.perf_counter()
        colony = Colony(cfg)
        renderer = mujoco.Renderer(colony.model, req.size, req.size)
        timings["build_s"] = time.perf_counter() - t0
        n_frames = int(round(req.seconds_per_day * req.fps))
        n_samples = 0
        while sample_frame_indices(n_samples, req.fps, req.every, req.gap, req.m)[-1] < n_frames:
            n_samples += 1
        needed = {f for s in range(n_samples)
                  for f in sample_frame_indices(s, req.fps, req.every, req.gap, req.m)}
        render = None if (req.video or req.frames) else needed
        next_id, done = 0, 0.0
        for day in days:
            label = "Stable" if day < 0 else "Unstable"
            colony.reset(day)
            events: dict[int, list] = {}
            writer = None
            if req.video:
                (stage / "video").mkdir(exist_ok=True)
                path = stage / "video" / f"{day_name(day)}.mp4"
                writer = Mp4Writer(path, req.fps, (req.size, req.size))
            frame_dir = stage / "frames" / day_name(day)
            if req.frames:
                frame_dir.mkdir(parents=True)

            try:
                stream = _day_frames(colony, req, day, render, renderer, events, frame_rows,
                                     writer, frame_dir if req.frames else None,
                                     (lambda t, base=done: advance(base + t)) if advance else None)
                ids = extract_flow_samples(stream, req.fps, stage / "flows", every=req.every,
                                           gap=req.gap, m=req.m, method=req.method, label=label,
                                           start_id=next_id)
            except BaseException:
                if writer is not None:
                    writer.discard()
                raise
            if writer is not None:
                writer.commit()
            done += req.seconds_per_day
            for sid in ids:
                s = sid - next_id
                labels.append([sid, f"{label}/{sid:05d}", label, day_name(day),
                               round(s * req.every, 4), round(float(aggression(day)), 4)])
                idx = sample_frame_indices(s, req.fps, req.every, req.gap, req.m)
                flow_boxes += sample_boxes(sid, idx, events, SAMPLE / req.size)
            if label == "Stable":
                stable_ids += ids
            next_id = ids[-1] + 1
        timings["simulate_s"] = time.perf_counter() - t0 - timings["build_s"]
        flows = stage / "flows"
        if len(stable_ids) >= 2:
            for k, (train, test) in enumerate(stable_splits(stable_ids, req.seed), start=1):
                (flows / f"split{k}").mkdir()
                _write_csv(flows / f"split{k}" / "train.csv", None,
                           [[f"Stable/{i:05d}"] for i in train])
                _write_csv(flows / f"split{k}" / "test.csv", None,
                           [[f"Stable/{i:05d}"] for i in test])
        write_json_atomic(flows / "bins.json", day_bins(labels))
        head = ["sample_id", "path", "label", "day", "t_start_s", "aggression"]
        _write_csv(stage / "labels.csv", head, labels)
        _write_csv(flows / "samples.csv", head, labels)
        _write_csv(flows / "boxes.csv", ["sample_id", "k", "x", "y", "w", "h"], flow_boxes)
        _write_csv(stage / "boxes.csv", ["day", "frame", "t_s", "kind", "ant_a", "ant_b",
                                         "x", "y", "w", "h"], frame_rows)
        for name in PRODUCTS:  # --overwrite: replace the previous run's products as a whole
            old = out / name
            if old.is_dir():
                shutil.rmtree(old)
            elif old.exists():
                old.unlink()
        written = {}
        for name in PRODUCTS:
            if (stage / name).exists():
                os.replace(stage / name, out / name)
                written[name] = out / name
    finally:
        if renderer is not None:
            renderer.close()
        shutil.rmtree(stage, ignore_errors=True)
    n_stable = len(stable_ids)
    run.timings.update(timings)
    run.record(days=[day_name(d) for d in days],
               samples={"Stable": n_stable, "Unstable": len(labels) - n_stable},
               boxed_subframes=len(flow_boxes), frame_events=len(frame_rows),
               timestep=colony.model.opt.timestep, splits=len(stable_ids) >= 2)
    written["manifest.json"] = run.path
    return written
