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


# The dissertation's metric first (Fig 3.4 and 3.5: "average errors for all predictions in
# 5-robot teams", F2, F3 and Head), the Head's alone beside it.
METRICS = (("all_predictions_cm", "all predictions (F2, F3, H)"), ("head_cm", "Head"))


def plot_sigma(results: dict, path: str | os.PathLike) -> None:
    """Fig 3.4: error on 5-robot teams against the Rand-Only σ, mean ± std: all predictions
    (the text's metric), and the Head alone."""
    plt = _plt()
    sig = sorted((float(c[3:]), c) for c in results["configs"] if c.startswith("ro_"))
    fig, axes = plt.subplots(1, 2, figsize=(9.0, 3.4), sharex=True)
    for ax, (key, what) in zip(axes, METRICS, strict=True):
        cells = [_full(results, c)[key] for _, c in sig]
        ax.errorbar([s * 100 for s, _ in sig], [c["mean"] for c in cells],
                    yerr=[c["std"] for c in cells], marker="o", capsize=3, color="#d62728")
        ax.set_xlabel("Rand-Only σ (% of the 11 cm robot size)")
        ax.set_ylabel(f"error, {what} (cm)")
    axes[0].set_title("Fig 3.4: Rand-Only over σ, all predictions")
    axes[1].set_title("the Head alone")
    fig.tight_layout()
    save_png(fig, path)


def plot_budgets(results: dict, configs: list[str], path: str | os.PathLike) -> None:
    """Fig 3.5: error against the training budget for each configuration, mean ± std: all
    predictions (the text's metric), and the Head alone."""
    plt = _plt()
    fig, axes = plt.subplots(1, 2, figsize=(10.0, 3.6), sharex=True)
    for ax, (key, what) in zip(axes, METRICS, strict=True):
        for config in configs:
            if config not in results["configs"]:
                continue
            cells = sorted(results["configs"][config].values(), key=lambda c: c["instances"])
            ax.errorbar([c["instances"] for c in cells], [c[key]["mean"] for c in cells],
                        yerr=[c[key]["std"] for c in cells], marker="o", capsize=3,
                        label=_label(config))
        ax.set_xlabel("training instances (3 robots)")
        ax.set_ylabel(f"error, {what} (cm)")
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    save_png(fig, path)


def plot_stepwise(results: dict, path: str | os.PathLike) -> None:
    """Fig 3.6: step-wise Head (solid) and F2 (dashed) error on the 5-robot tests, 100 %."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6.2, 3.8))
    shown = [c for c in results["configs"]
             if not c.startswith("ro_") or c == results["baseline"]]
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
        for config, colour in ((results["baseline"], "#1f77b4"), ("srs_max", "#d62728")):
            if config in dist:
                ax.hist(np.asarray(dist[config][pair]), bins=40, histtype="step", density=True,
                        color=colour, label=_label(config))
        ax.set_xlabel(f"{pair} distance (cm)")
        ax.legend(fontsize=7)
    axes[0].set_ylabel("density")
    fig.tight_layout()
    save_png(fig, path)


def plot_all(results: dict, out: str | os.PathLike, picks: list[str]) -> None:
    """Every figure of the chapter from a `results.json` (what `experiment srs` ends with; a
    committed one is re-plotted with `python -m viz.srs_figures FOLDER`)."""
    from pathlib import Path

    out = Path(out)
    plot_sigma(results, out / "fig3_4.png")
    plot_budgets(results, [f"srs_{p}" for p in picks], out / "fig3_5a.png")
    plot_budgets(results, ["passive", results["baseline"], "srs_med"], out / "fig3_5b.png")
    plot_stepwise(results, out / "fig3_6.png")
    if results.get("distances"):
        plot_distances(results, out / "fig3_7.png")


def table(results: dict) -> str:
    """Fig 3.5's numbers as a markdown table: per configuration and budget, all predictions
    mean ± std (the text's metric), the Head's mean beside it (cm)."""
    budgets = sorted({c["instances"] for cells in results["configs"].values()
                      for c in cells.values()})
    lines = ["| configuration | " + " | ".join(f"{b} instances" for b in budgets) + " |",
             "|---" * (len(budgets) + 1) + "|"]
    for config, cells in results["configs"].items():
        by = {c["instances"]: c for c in cells.values()}
        row = [f"{by[b]['all_predictions_cm']['mean']:.1f} ± "
               f"{by[b]['all_predictions_cm']['std']:.1f} (H {by[b]['head_cm']['mean']:.1f})"
               if b in by else "" for b in budgets]
        lines.append(f"| {_label(config)} | " + " | ".join(row) + " |")
    return "\n".join(lines)


if __name__ == "__main__":
    import json
    import sys
    from pathlib import Path

    folder = Path(sys.argv[1])
    results = json.loads((folder / "results.json").read_text())
    if "--table" in sys.argv:
        print(table(results))
    else:
        plot_all(results, folder, list(results["profile"]["picks"]))
