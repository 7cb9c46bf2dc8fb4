"""Figures of `experiment srs` (chapter 3): Fig 3.4 (σ sweep), Fig 3.5 (policies over budgets),
Fig 3.6 (step-wise errors on 5-robot teams) and Fig 3.7 (distance histograms)."""

from __future__ import annotations

import os

import numpy as np

from viz.figures import save_png

LABELS = {"passive": "Passive", "srs_max": "SRS-Max", "srs_q3": "SRS-Q3", "srs_q2": "SRS-Q2",
          "srs_med": "SRS-Med"}


def _label(config: str) -> str:
    if config.startswith("ro_"):
        return f"Rand-Only σ={float(config[3:]) * 100:.0f} %"
    return LABELS.get(config, config)


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _full(results: dict, config: str) -> dict:
    """A configuration's cell at the largest budget (100 %)."""
    cells = results["configs"][config]
    return cells[max(cells, key=float)]


def plot_sigma(results: dict, path: str | os.PathLike) -> None:
    """Fig 3.4: Head error on 5-robot teams against the Rand-Only σ, mean ± std."""
    plt = _plt()
    sig = sorted((float(c[3:]), c) for c in results["configs"] if c.startswith("ro_"))
    cells = [_full(results, c)["head_cm"] for _, c in sig]
    fig, ax = plt.subplots(figsize=(5.2, 3.4))
    ax.errorbar([s * 100 for s, _ in sig], [c["mean"] for c in cells],
                yerr=[c["std"] for c in cells], marker="o", capsize=3, color="#d62728")
    ax.set_xlabel("Rand-Only σ (% of the 11 cm robot size)")
    ax.set_ylabel("Head error, 5-robot test (cm)")
    ax.set_title("Fig 3.4: Rand-Only over σ")
    fig.tight_layout()
    save_png(fig, path)


def plot_budgets(results: dict, configs: list[str], path: str | os.PathLike) -> None:
    """Fig 3.5: Head error against the training budget for each configuration, mean ± std."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(5.6, 3.6))
    for config in configs:
        if config not in results["configs"]:
            continue
        cells = sorted(results["configs"][config].values(), key=lambda c: c["instances"])
        ax.errorbar([c["instances"] for c in cells], [c["head_cm"]["mean"] for c in cells],
                    yerr=[c["head_cm"]["std"] for c in cells], marker="o", capsize=3,
                    label=_label(config))
    ax.set_xlabel("training instances (3 robots)")
    ax.set_ylabel("Head error, 5-robot test (cm)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    save_png(fig, path)


def plot_stepwise(results: dict, path: str | os.PathLike) -> None:
    """Fig 3.6: step-wise Head (solid) and F2 (dashed) error on the 5-robot tests, 100 %."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6.2, 3.8))
    shown = [c for c in results["configs"] if not c.startswith("ro_") or c == "ro_0.75"]
    for i, config in enumerate(shown):        # one colour per configuration shown
        cell = _full(results, config)
        colour = f"C{i % 10}"
        for robot, style in (("H", "-"), ("F2", "--")):
            vals = cell["per_step_cm"].get(robot, [])[:13]    # up to the 13th prediction
            keep = [k for k, v in enumerate(vals) if v is not None]
            ax.plot([(cell["first_step"] + k) * cell["step_s"] for k in keep],
                    [vals[k] for k in keep], style, color=colour,
                    label=f"{_label(config)} {robot}")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("error (cm)")
    ax.legend(fontsize=6, ncol=2)
    fig.tight_layout()
    save_png(fig, path)


def plot_distances(results: dict, path: str | os.PathLike) -> None:
    """Fig 3.7: H–F and F–T distance histograms, SRS-Max (66 %) against Rand-Only."""
    plt = _plt()
    dist = results["distances"]
    fig, axes = plt.subplots(1, 2, figsize=(7.2, 3.2))
    for ax, pair in zip(axes, ("H-F", "F-T"), strict=True):
        for config, colour in (("ro_0.75", "#1f77b4"), ("srs_max", "#d62728")):
            if config in dist:
                ax.hist(np.asarray(dist[config][pair]), bins=40, histtype="step", density=True,
                        color=colour, label=_label(config))
        ax.set_xlabel(f"{pair} distance (cm)")
        ax.legend(fontsize=7)
    axes[0].set_ylabel("density")
    fig.tight_layout()
    save_png(fig, path)
