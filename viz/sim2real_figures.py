"""The data-efficiency curve of `experiment sim2real`: Head error on held-out real instances
against the share of real training data, real-only and sim-pre-trained, with the sim-only level."""

from __future__ import annotations

import os

import numpy as np

from viz.figures import save_png


def plot_curve(results: dict, path: str | os.PathLike) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.0, 4.0))
    for arm, label, style in (("real", "real only", "o-"),
                              ("finetune", "sim pre-trained, fine-tuned", "s-"),
                              ("mixed", "sim and real mixed", "^-"),
                              ("finetune-mixed", "sim pre-trained, fine-tuned mixed", "d-"),
                              ("finetune-frozen", "sim pre-trained, encoders frozen", "v-")):
        if arm not in results["arms"]:          # results written before the mixed arm
            continue
        cells = results["arms"][arm]
        x = np.array([float(f) * 100 for f in cells])
        m = np.array([c["head_cm"]["mean"] for c in cells.values()])
        s = np.array([c["head_cm"]["std"] for c in cells.values()])
        ax.errorbar(x, m, yerr=s, fmt=style, capsize=3, label=label)
    if "sim" in results["arms"]:        # a run of some arms (`--arm`) may lack it
        sim = results["arms"]["sim"]["0"]["head_cm"]
        ax.axhline(sim["mean"], color="grey", ls="--", label=f"sim only ({sim['mean']:.1f} cm)")
    ax.set_xscale("log")
    shares = [float(f) * 100 for f in results["profile"]["fractions"]]
    ax.set_xticks(shares, [f"{v:g}" for v in shares])
    ax.minorticks_off()
    ax.set_xlabel("real training data used (% of the pool, log scale)")
    ax.set_ylabel("Head error on held-out real instances (cm)")
    n = results["profile"]["seeds"]
    ax.set_title(f"Sim-to-real: mean ± std over {n} seeds (one held-out fold each)", fontsize=9)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    save_png(fig, path, tight=True)
