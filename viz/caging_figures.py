"""Fig 2.3-style snapshots of a caging run: the object, the boundary, the robots and their
chain at a few moments, with the Tail's estimate of the Head where it has one."""

from __future__ import annotations

import os

import numpy as np

from viz.figures import save_png


def plot_snapshots(frames: list[dict], cfg, arena: tuple[float, float],
                   path: str | os.PathLike, title: str = "", zoom: float | None = None) -> None:
    """frames: dicts with t (s), poses (n, 3) Head first, optional head_estimate (2,), label;
    `zoom`: show only this half-width (m) around the object instead of the whole arena."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = (len(frames) + 3) // 4
    fig, axes = plt.subplots(rows, min(4, len(frames)), figsize=(3.0 * min(4, len(frames)),
                                                                  2.4 * rows), squeeze=False)
    for ax in axes.ravel()[len(frames):]:
        ax.axis("off")
    c = np.asarray(cfg.centre)
    for ax, frame in zip(axes.ravel(), frames, strict=False):
        ax.add_patch(plt.Circle(c, cfg.object_radius, color="#888888"))
        ax.add_patch(plt.Circle(c, cfg.ring_radius, fill=False, ls="--", color="#444444"))
        p = np.asarray(frame["poses"])
        ax.plot(p[:, 0], p[:, 1], "-", color="#1f77b4", lw=1)
        ax.scatter(p[1:-1, 0], p[1:-1, 1], s=18, color="#1f77b4", zorder=3)
        ax.scatter(*p[0, :2], s=30, color="#d62728", zorder=4, label="Head")
        ax.scatter(*p[-1, :2], s=30, color="#2ca02c", zorder=4, label="Tail")
        est = frame.get("head_estimate")
        if est is not None and np.all(np.isfinite(est)):
            ax.scatter(*est, s=40, facecolors="none", edgecolors="#d62728", zorder=4,
                       label="Tail's estimate of Head")
        half = (zoom, zoom) if zoom else (arena[0] / 2, arena[1] / 2)
        ax.set_xlim(c[0] - half[0], c[0] + half[0])
        ax.set_ylim(c[1] - half[1], c[1] + half[1])
        ax.set_aspect("equal")
        ax.set_xticks([])
        ax.set_yticks([])
        ax.set_title(f"t = {frame['t']:.1f} s {frame.get('label', '')}", fontsize=8)
    axes[0][0].legend(fontsize=6, loc="upper left")
    if title:
        fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    save_png(fig, path)
