"""`stats --compare --plot`: each pooled motion feature of two ThymioLoc files, side by side."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from viz.figures import save_png  # noqa: E402

SHOWN = ("spacing_cm", "speed_cm_s", "turn_deg_s", "heading_change_deg", "accel_cm_s2",
         "jitter_cm", "wait_share", "speed_acf_lag1", "turn_acf_lag1")


def compare_figure(path: Path, a: dict, b: dict, rows: list[dict], labels: tuple[str, str]
                   ) -> None:
    """A 3 x 3 grid of histograms (pooled over robots), KS distance in each title."""
    ks = {r["feature"]: r["ks"] for r in rows if r["robot"] == "pooled"}
    fig, axes = plt.subplots(3, 3, figsize=(12, 9))
    for ax, name in zip(axes.ravel(), SHOWN, strict=True):
        va, vb = a[name]["pooled"], b[name]["pooled"]
        lo, hi = np.percentile(np.r_[va, vb], [0.5, 99.5])
        bins = np.linspace(lo, hi if hi > lo else lo + 1, 40)
        ax.hist(va, bins, density=True, alpha=0.5, label=labels[0])
        ax.hist(vb, bins, density=True, alpha=0.5, label=labels[1])
        ax.set_title(f"{name}  (KS {ks.get(name, float('nan')):.2f})", fontsize=9)
    axes[0, 0].legend(fontsize=8)
    save_png(fig, path, tight=True)
