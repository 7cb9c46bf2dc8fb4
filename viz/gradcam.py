"""Grad-CAM (seed §4.6.5) on the DSVDD feature map through the Classifier, and how to show it.

α_k = mean_ij ∂y'/∂F^k_ij (y' = Classifier logit, F = DSVDD feature map), h = ReLU(Σ_k α_k F^k):
where motion pushes the "unstable" likelihood up. For display (§4.7.4) the position-wise minimum
over all shown samples is subtracted and only the top 5 % of each frame is coloured.
"""

from __future__ import annotations

import os
from collections.abc import Sequence

import cv2
import numpy as np

from macrostate_mj.core.errors import UserError

Box = tuple[float, float, float, float]  # x, y, w, h in heatmap pixels, (0, 0) = top-left corner


def gradcam(dsvdd, classifier, x: np.ndarray, batch: int = 128) -> np.ndarray:
    """N × 8 × 8 Grad-CAM maps for inputs x (N × 2m × 64 × 64 in [−1, 1])."""
    import torch

    maps = []
    for i in range(0, len(x), batch):
        xb = torch.from_numpy(np.ascontiguousarray(x[i:i + batch]))
        fmap = dsvdd.feature_map(xb).detach().requires_grad_(True)
        logit = classifier(fmap.flatten(1))
        (grad,) = torch.autograd.grad(logit.sum(), fmap)  # samples are independent
        alpha = grad.mean(dim=(2, 3), keepdim=True)
        maps.append(torch.relu((alpha * fmap).sum(1)).detach().numpy())
    return np.concatenate(maps).astype(np.float32)


def upsample(maps: np.ndarray, size: int = 64) -> np.ndarray:
    """Resize N × h × w maps to N × size × size (bilinear), for overlays on the `img` frames."""
    return np.stack([cv2.resize(m, (size, size), interpolation=cv2.INTER_LINEAR) for m in maps])


def top_share(maps: np.ndarray, share: float = 0.05) -> np.ndarray:
    """§4.7.4 display: subtract the position-wise minimum over samples, keep each map's top share.

    Returns the shifted maps with everything below each map's (1 − share) quantile set to 0.
    """
    shifted = maps - maps.min(axis=0, keepdims=True)
    q = np.quantile(shifted.reshape(len(maps), -1), 1.0 - share, axis=1)
    keep = (shifted >= q[:, None, None]) & (shifted > 0)
    return np.where(keep, shifted, 0.0).astype(np.float32)


def overlay(img: np.ndarray, heat: np.ndarray, alpha: float = 0.5) -> np.ndarray:
    """Colour the non-zero part of `heat` (JET, scaled to its max) over an RGB uint8 frame."""
    peak = float(heat.max())
    if peak <= 0:
        return img.copy()
    colour = cv2.applyColorMap(np.uint8(255 * heat / peak), cv2.COLORMAP_JET)[..., ::-1]
    mask = (heat > 0)[..., None]
    blend = (1 - alpha) * img.astype(np.float32) + alpha * colour.astype(np.float32)
    return np.where(mask, blend, img).astype(np.uint8)


def overlay_grid(imgs: np.ndarray, heats: np.ndarray, scale: int = 3) -> np.ndarray:
    """One RGB image: a row per sample (N × m frames), each frame with its heatmap overlaid."""
    rows = [np.concatenate([overlay(f, heats[i]) for f in imgs[i]], axis=1)
            for i in range(len(imgs))]
    grid = np.concatenate(rows, axis=0)
    return cv2.resize(grid, None, fx=scale, fy=scale, interpolation=cv2.INTER_NEAREST)


def write_png(path: str | os.PathLike, rgb: np.ndarray) -> None:
    """Atomically write an RGB image as PNG."""
    from macrostate_mj.core.io import atomic_path

    ok, buf = cv2.imencode(".png", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    if not ok:
        raise UserError(f"could not encode {path}")
    with atomic_path(path) as tmp:
        tmp.write_bytes(buf.tobytes())


def write_mp4(path: str | os.PathLike, frames: Sequence[np.ndarray], fps: float = 2.0) -> None:
    """Write RGB frames as an MP4; the file appears under its name only when complete."""
    from macrostate_mj.core.io import Mp4Writer

    h, w = frames[0].shape[:2]
    with Mp4Writer(path, fps, (w, h)) as writer:
        for f in frames:
            writer.write(f)


def _in_boxes(px: np.ndarray, py: np.ndarray, bxs: Sequence[Box], tolerance: float) -> np.ndarray:
    """Which of the points (px, py) lie in at least one box grown by `tolerance` px."""
    inside = np.zeros(np.broadcast(px, py).shape, bool)
    for x, y, w, h in bxs:
        inside |= ((x - tolerance <= px) & (px <= x + w + tolerance) &
                   (y - tolerance <= py) & (py <= y + h + tolerance))
    return inside


def box_share(boxes: Sequence[Sequence[Box]], shape: tuple[int, int],
              tolerance: float = 0.0) -> float:
    """Chance level of the pointing game: the mean share of pixel centres inside a sample's boxes
    (what a peak placed uniformly at random would score). NaN when no sample has a box."""
    rows, cols = np.mgrid[0:shape[0], 0:shape[1]]
    shares = [_in_boxes(cols + 0.5, rows + 0.5, bxs, tolerance).mean() for bxs in boxes if bxs]
    return float(np.mean(shares)) if shares else float("nan")


def pointing_game(heatmaps: np.ndarray, boxes: Sequence[Sequence[Box]],
                  tolerance: float = 0.0) -> float:
    """Share of samples whose heatmap peak lies in one of their ground-truth boxes.

    heatmaps: N × H × W; boxes[i]: (x, y, w, h) boxes in the same pixel frame (pixel (r, c) has
    its centre at (c + 0.5, r + 0.5)), grown by `tolerance` px on each side. Samples without a
    box are left out; a map with no positive value points nowhere and counts as a miss.
    Returns NaN when no sample has a box.
    """
    heatmaps = np.asarray(heatmaps)
    if len(heatmaps) != len(boxes):
        raise ValueError(f"{len(heatmaps)} heatmaps but {len(boxes)} box lists")
    hits = total = 0
    for heat, bxs in zip(heatmaps, boxes, strict=True):
        if len(bxs) == 0:
            continue
        total += 1
        if not np.any(heat > 0):
            continue
        r, c = np.unravel_index(int(np.argmax(heat)), heat.shape)
        hits += bool(_in_boxes(np.array(c + 0.5), np.array(r + 0.5), bxs, tolerance))
    return hits / total if total else float("nan")


def top_pixels(heat: np.ndarray, share: float = 0.05) -> np.ndarray:
    """Boolean mask of a map's top `share` pixels (ceil(share × pixels) of them; ties broken by
    position, row-major). A flat map points nowhere: an empty mask."""
    flat = heat.ravel()
    mask = np.zeros(flat.shape, bool)
    if flat.max() > flat.min():
        mask[np.argsort(-flat, kind="stable")[:max(1, int(np.ceil(share * flat.size)))]] = True
    return mask.reshape(heat.shape)


def box_counts(heatmaps: np.ndarray, boxes: Sequence[Sequence[Box]], share: float = 0.05
               ) -> tuple[np.ndarray, np.ndarray]:
    """Where each map's top `share` pixels lie against its sample's boxes, N × 2 ints per
    measure, (0, 0) for a sample without a box:

    - boxes hit: (boxes one of those pixels' centres lies in, boxes), the pointing game of
      §4.7.4's displays, which colour a map's top 5 %;
    - pixels on boxes: (those pixels inside a box, those pixels), how much of what a map shows
      lies on the action. Scattering the pixels does not pay here: uniform noise scores the
      boxes' share of the frame. A flat map shows nothing and misses with all its pixels, as
      in `pointing_game`."""
    hit, on = np.zeros((len(heatmaps), 2), int), np.zeros((len(heatmaps), 2), int)
    for i, (heat, bxs) in enumerate(zip(heatmaps, boxes, strict=True)):
        if not bxs:
            continue
        r, c = np.nonzero(top_pixels(heat, share))
        hit[i] = sum(bool(_in_boxes(c + 0.5, r + 0.5, [b], 0.0).any()) for b in bxs), len(bxs)
        on[i] = (int(_in_boxes(c + 0.5, r + 0.5, bxs, 0.0).sum()),
                 max(1, int(np.ceil(share * heat.size))))
    return hit, on


def centre_prior(n: int, shape: tuple[int, int]) -> np.ndarray:
    """N copies of a map peaked at the frame's centre (minus the distance to it): a baseline
    that knows only that a nest's action tends to be away from its walls."""
    rows, cols = np.mgrid[0:shape[0], 0:shape[1]]
    dist = np.hypot(rows + 0.5 - shape[0] / 2, cols + 0.5 - shape[1] / 2)
    return np.broadcast_to(-dist, (n, *shape)).astype(np.float32)


def hit_share(hits: np.ndarray, rng: np.random.Generator, resamples: int = 2000,
              level: float = 0.95) -> dict[str, float | int | None]:
    """Σ hits / Σ totals of per-sample (hits, total) counts (either of `box_counts`)
    with a percentile bootstrap interval over samples; None where no sample counts."""
    hits = hits[hits[:, 1] > 0]
    if not len(hits):
        return {"share": None, "lo": None, "hi": None, "samples": 0, "total": 0}
    draws = rng.integers(0, len(hits), (resamples, len(hits)))
    boot = hits[draws, 0].sum(1) / hits[draws, 1].sum(1)
    tail = 100 * (1 - level) / 2
    return {"share": float(hits[:, 0].sum() / hits[:, 1].sum()),
            "lo": float(np.percentile(boot, tail)), "hi": float(np.percentile(boot, 100 - tail)),
            "samples": int(len(hits)), "total": int(hits[:, 1].sum())}
