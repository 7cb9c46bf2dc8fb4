"""Figures of `experiment retlo`: Fig 2.7 (bars), Fig 2.8 (step-wise lines), Fig 2.9 (video)."""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

import numpy as np

from macrostate_mj.core.io import Mp4Writer
from viz.figures import save_png

MODEL_STYLE = {"heuristic2x": ("2X heuristic", "#999999"), "fc": ("FC", "#1f77b4"),
               "lstm": ("LSTM (ours)", "#d62728")}


def plot_overall(results: dict, path: str | os.PathLike) -> None:
    """Fig 2.7: mean error of the unseen robots per model and test set, ± std over seeds."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    tests = results["tests"]
    fig, ax = plt.subplots(figsize=(max(5.0, 1.2 + 2.4 * len(tests)), 3.6))
    width = 0.8 / len(MODEL_STYLE)
    for i, (model, (label, colour)) in enumerate(MODEL_STYLE.items()):
        means = [results["results"][t["name"]][model]["mean_error_cm"]["mean"] for t in tests]
        stds = [results["results"][t["name"]][model]["mean_error_cm"]["std"] for t in tests]
        xs = np.arange(len(tests)) + (i - 1) * width
        ax.bar(xs, means, width, yerr=stds, capsize=3, color=colour, label=label)
        for x, m in zip(xs, means, strict=True):
            ax.text(x, m, f"{m:.1f}", ha="center", va="bottom", fontsize=7)
    ax.set_xticks(np.arange(len(tests)),
                  [f"{t['n_robots']} robots\n{t['name']}" for t in tests], fontsize=8)
    ax.set_ylabel("mean error of unseen robots (cm)")
    ax.set_title(f"ReTLo error, mean ± std over {results['seeds']} seeds")
    ax.legend(fontsize=8)
    fig.tight_layout()
    save_png(fig, path)


def plot_stepwise(results: dict, test: str, path: str | os.PathLike) -> None:
    """Fig 2.8: step-wise error of F2 and H (or H alone in 3-robot teams), ± std over seeds."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    res = results["results"][test]
    robots = [r for r in ("F2", "H") if r in res["lstm"]["per_robot_step_cm"]]
    fig, ax = plt.subplots(figsize=(6.4, 3.8))
    for model, (label, colour) in MODEL_STYLE.items():
        agg = res[model]
        for robot, style in zip(robots, ("--", "-"), strict=False):
            style = style if len(robots) > 1 else "-"
            cells = agg["per_robot_step_cm"][robot]
            keep = [i for i, c in enumerate(cells) if c["mean"] is not None]
            secs = [(agg["first_step"] + i) * agg["step_s"] for i in keep]
            mean = np.array([cells[i]["mean"] for i in keep])
            std = np.array([cells[i]["std"] for i in keep])
            ax.errorbar(secs, mean, yerr=std, fmt=style, marker="o", ms=3, capsize=2,
                        color=colour, label=f"{label}, {robot}")
    ax.set_xlabel("time in the instance (s); true history before the first point")
    ax.set_ylabel("error (cm)")
    ax.set_title(f"Step-wise error, {test}")
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    save_png(fig, path)


def _colours(n: int) -> list[tuple[int, int, int]]:
    """BGR per robot in file order: Head pink, Tail yellow, Followers blue to green (Fig 2.9)."""
    mids = [(255, int(80 + 150 * i / max(1, n - 3)), 40) for i in range(n - 2)]
    return [(180, 60, 255), *mids, (0, 220, 255)]


def _triangle(x: float, y: float, o_deg: float, size: float) -> np.ndarray:
    """Isosceles triangle in pixels (y down), apex along heading o = atan2(-dy, dx)."""
    a = np.deg2rad(o_deg)
    fwd, left = np.array([np.cos(a), -np.sin(a)]), np.array([-np.sin(a), -np.cos(a)])
    c = np.array([x, y])
    pts = [c + fwd * size * 0.6, c - fwd * size * 0.4 + left * size * 0.35,
           c - fwd * size * 0.4 - left * size * 0.35]
    return np.round(np.array(pts)).astype(np.int32)


def write_video(path: str | os.PathLike, true_px: np.ndarray, est_px: np.ndarray,
                px_per_cm: float, fps: float = 2.0,
                backdrop: Callable[[np.ndarray], np.ndarray] | None = None,
                frame_size: tuple[int, int] | None = None,
                colours: list[tuple[int, int, int]] | None = None,
                est_cov_px: np.ndarray | None = None, estimator: str = "ReTLo") -> Path:
    """Fig 2.9 as an MP4: truth as triangles, estimates as circles with heading arrows, robot
    ids and a legend; with `est_cov_px` (instances, steps, robots, 2, 2; pixels², y down)
    each estimate's 90 % ellipse too; over `backdrop(true pose px (robots, 3)) -> BGR camera
    frame` where one is given (the lab scene rendered at the true poses, `frame_size` its
    width and height, `colours` BGR of its robots' markers), else over a plain floor.

    true_px, est_px: (instances, steps, robots, 3) pixels/degrees in file order, est NaN where
    nothing is estimated. Instances play one after another at the 2 Hz log rate.
    """
    size = 11.0 * px_per_cm  # a Thymio is about 11 cm long
    lo = np.floor(np.nanmin(true_px[..., :2], axis=(0, 1, 2)) - 2 * size).astype(int)
    hi = np.ceil(np.nanmax(true_px[..., :2], axis=(0, 1, 2)) + 2 * size).astype(int)
    if backdrop is not None and frame_size is not None:   # the camera's frame bounds the view
        lo, hi = np.maximum(lo, 0), np.minimum(hi, frame_size)
    w, h = (int(v) - int(v) % 2 for v in hi - lo)
    with Mp4Writer(path, fps, (w, h)) as writer:
        _draw(writer, true_px, est_px, lo, (w, h), size, backdrop,
              colours or _colours(true_px.shape[2]), est_cov_px, estimator)
    return Path(path)


def write_video_gaussian(path: str | os.PathLike, world: np.ndarray, est: np.ndarray,
                         cov: np.ndarray | None, px_per_cm: float) -> Path:
    """`write_video` of chains and estimates in metres (B, S, N, 3), file order, with the
    estimates' 90 % ellipses where `cov` (B, S, N, 2, 2; m²) is given."""
    from estimators.retlo import CM_PER_M
    from estimators.retlo.files import world_to_pixels
    from estimators.retlo.gaussian import scale_cov

    scale = CM_PER_M * px_per_cm           # metres → pixels; image y points down
    cov_px = None if cov is None else scale_cov(cov, scale, -scale)
    return write_video(path, world_to_pixels(world, px_per_cm), world_to_pixels(est, px_per_cm),
                       px_per_cm, est_cov_px=cov_px)


def _ellipse(frame: np.ndarray, centre: tuple[float, float], cov: np.ndarray,
             colour: tuple[int, int, int]) -> None:
    """The 90 % region of N(centre, cov) (pixels) as a closed outline."""
    import cv2

    from estimators.retlo.gaussian import ellipse

    if not np.all(np.isfinite(cov)):
        return
    pts = np.round(ellipse(np.asarray(centre, float), cov, 0.9)).astype(np.int32)
    cv2.polylines(frame, [pts], True, colour, 2, cv2.LINE_AA)


def _draw(writer, true_px: np.ndarray, est_px: np.ndarray, lo: np.ndarray,
          wh: tuple[int, int], size: float, backdrop,
          colours: list[tuple[int, int, int]], est_cov_px: np.ndarray | None = None,
          estimator: str = "ReTLo") -> None:
    """Write every frame of every instance to an open `Mp4Writer`."""
    import cv2

    from macrostate_mj.core.draw import label
    from macrostate_mj.formats.thymioloc import robot_names

    names = robot_names(true_px.shape[2])
    legend = (f"disc + arrow: {estimator} estimate and heading"
              if np.isfinite(est_px[..., 2]).any() else f"disc: {estimator} estimate")
    for inst in range(true_px.shape[0]):
        for step in range(true_px.shape[1]):
            frame = np.full((wh[1], wh[0], 3), 245, np.uint8)
            if backdrop is not None:
                full = backdrop(true_px[inst, step])
                crop = full[lo[1]:lo[1] + wh[1], lo[0]:lo[0] + wh[0]]
                frame[:crop.shape[0], :crop.shape[1]] = crop
            for r, colour in enumerate(colours):
                x, y, o = true_px[inst, step, r]
                tri = _triangle(x - lo[0], y - lo[1], o, size)
                if backdrop is None:
                    cv2.fillPoly(frame, [tri], colour, cv2.LINE_AA)
                cv2.polylines(frame, [tri], True, colour if backdrop is not None else (0, 0, 0),
                              2 if backdrop is not None else 1, cv2.LINE_AA)
                label(frame, names[r], (int(x - lo[0] + 0.6 * size), int(y - lo[1] - 0.5 * size)),
                      0.4)
                ex, ey, eo = est_px[inst, step, r]
                if np.isnan(ex):
                    continue
                c = (int(round(ex - lo[0])), int(round(ey - lo[1])))
                if est_cov_px is not None:
                    _ellipse(frame, (ex - lo[0], ey - lo[1]), est_cov_px[inst, step, r], colour)
                cv2.circle(frame, c, int(size * 0.3), colour, -1, cv2.LINE_AA)
                cv2.circle(frame, c, int(size * 0.3), (0, 0, 0), 1, cv2.LINE_AA)
                if np.isnan(eo):                # an estimator without headings
                    continue
                a = np.deg2rad(eo)
                tip = (int(round(c[0] + np.cos(a) * size * 0.5)),
                       int(round(c[1] - np.sin(a) * size * 0.5)))
                cv2.arrowedLine(frame, c, tip, (0, 0, 0), 2, cv2.LINE_AA, tipLength=0.35)
            known = "true history" if np.all(np.isnan(est_px[inst, step])) else "estimated"
            label(frame, f"instance {inst + 1}  t = {step / 2:4.1f} s  ({known})", (8, 20), 0.5)
            label(frame, f"triangle: truth   {legend}"
                  + ("   ring: its 90 % region" if est_cov_px is not None else ""),
                  (8, wh[1] - 10), 0.4)
            writer.write_bgr(frame)
