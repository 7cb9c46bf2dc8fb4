"""Figures of `experiment retlo-sim`: Fig 2.2-style error curves and the test trajectories."""

from __future__ import annotations

import os

import numpy as np

from viz.figures import save_png


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_case(err: np.ndarray, names: list[str], sync: np.ndarray, threshold: float,
              title: str, path: str | os.PathLike) -> None:
    """Error (m) vs step per unseen robot, the accuracy line, and the communication steps."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7.0, 3.4))
    steps = np.arange(len(err))
    for j, name in enumerate(names):
        ax.plot(steps, err[:, j], lw=1.0, label=name)
    ax.axhline(threshold, color="k", ls="--", lw=1.0, label=f"{threshold:g} (diameter)")
    for s in sync:
        ax.axvline(s, color="0.8", lw=0.6, zorder=0)
    ax.set_xlabel("time step (30 Hz)")
    ax.set_ylabel("estimation error (m)")
    ax.set_title(title, fontsize=10)
    ax.set_xlim(0, len(err))
    ax.set_ylim(0, max(2 * threshold, float(np.nanmax(err, initial=0.0)) * 1.05))
    ax.legend(fontsize=8, ncol=len(names) + 1, loc="upper right")
    fig.tight_layout()
    save_png(fig, path, dpi=110)


def plot_trajectories(runs: dict[str, tuple[np.ndarray, str]], arena: tuple[float, float],
                      path: str | os.PathLike) -> None:
    """Every robot's path in each test run (Head bold), with the arena's walls."""
    plt = _pyplot()
    fig, axes = plt.subplots(1, len(runs), figsize=(4.2 * len(runs), 3.2), squeeze=False)
    w, h = arena
    for ax, (label, (poses, floor)) in zip(axes[0], runs.items(), strict=True):
        ax.add_patch(plt.Rectangle((-w / 2, -h / 2), w, h, fill=False, color="0.3"))
        for r in range(poses.shape[1]):
            ax.plot(poses[:, r, 0], poses[:, r, 1], lw=2.0 if r == 0 else 0.8,
                    label="Head" if r == 0 else None)
        ax.plot(*poses[0, :, :2].T, "k.", ms=4, label="start")
        ax.set_aspect("equal")
        ax.set_title(f"{label}, {floor} floor", fontsize=9)
        ax.legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    save_png(fig, path, dpi=110)
