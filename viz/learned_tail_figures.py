"""The learned Tail's learning curve and episode videos (`experiment learned-tail`)."""

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


def write_episode_video(path: Path, truth: np.ndarray, est: np.ndarray,
                        estimator: str) -> Path:
    """One Tail's episode as Fig 2.9 draws chains (`viz.retlo_figures.write_video`): every
    robot's true pose and the frozen estimator's estimates, at each log step.

    truth: (steps, robots, 3) m and rad, Tail first; est: (steps, robots, 2) m, Tail first,
    NaN where nothing is estimated (the estimator gives no headings: no arrows); `estimator`
    names it in the legend."""
    from estimators.retlo.files import world_to_pixels
    from macrostate_mj.formats.thymioloc import DEFAULT_PX_PER_CM
    from viz.retlo_figures import write_video

    est3 = np.concatenate([est, np.full((*est.shape[:2], 1), np.nan)], axis=-1)
    true_px = world_to_pixels(truth[None, :, ::-1])        # file order: Head first
    est_px = world_to_pixels(est3[None, :, ::-1])
    return write_video(path, true_px, est_px, DEFAULT_PX_PER_CM, estimator=estimator)
