"""The learned Tail's learning curve (`experiment learned-tail`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def plot_learning_curve(curve: list[dict], passive_return: float, path: Path) -> None:
    """Mean raw episode return (minus the summed Head error, m) per rollout against timesteps,
    with the passive Tail's mean return on the evaluation seeds for scale."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from macrostate_mj.core.io import atomic_path

    fig, ax = plt.subplots(figsize=(6, 3.5), dpi=120)
    if curve:
        steps = np.array([c["timesteps"] for c in curve])
        ret = np.array([c["mean_return"] for c in curve])
        ax.plot(steps, ret, lw=0.8, alpha=0.5, label="PPO, per rollout")
        k = max(1, len(ret) // 20)
        if len(ret) >= k > 1:
            smooth = np.convolve(ret, np.ones(k) / k, mode="valid")
            ax.plot(steps[k - 1:], smooth, lw=1.8, label=f"PPO, mean of {k} rollouts")
    ax.axhline(passive_return, color="k", ls="--", lw=1, label="passive Tail (evaluation)")
    ax.set_xlabel("timesteps")
    ax.set_ylabel("episode return (−Σ Head error, m)")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png")
    plt.close(fig)
