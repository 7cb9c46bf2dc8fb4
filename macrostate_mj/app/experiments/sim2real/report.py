"""`experiment sim2real`'s report: each arm's errors summarized over seeds and folds, per fit,
range candidate and ablation, and the lines the run prints."""

from __future__ import annotations

from collections import Counter
from dataclasses import asdict
from pathlib import Path

import numpy as np

from macrostate_mj.app.experiments.sim2real.config import ARMS, TUNED, Config
from macrostate_mj.app.experiments.sim2real.models import fold_of
from macrostate_mj.core.stats import cv_ratio, mean_std, paired_interval


def summarize(reports: list[dict], config: Config, n_real: int) -> dict:
    """Head and mean error (cm) per arm and fraction over seeds (and the Head's per seed, for
    paired comparisons between runs on the same folds); with the real arm, the
    sim-only / real-only ratio and, per fraction, the real-only data the fine-tuned model's error
    is worth."""
    out: dict = {"profile": asdict(config), "real_instances": n_real, "arms": {}}
    for arm in (a for a in ARMS if a in config.arms):
        out["arms"][arm] = {}
        for f in (0.0,) if arm == "sim" else config.fractions:
            cell = [r for r in reports if r["arm"] == arm and r["fraction"] == f]
            out["arms"][arm][f"{f:g}"] = {
                "head_cm": mean_std([r["head_cm"] for r in cell]),
                "mean_cm": mean_std([r["mean_cm"] for r in cell]),
                "count": max(r["count"] for r in cell),
                "head_cm_by_seed": {str(r["seed"]): r["head_cm"] for r in cell}}
    real = out["arms"].get("real")
    if real is None:
        return out
    full = real[f"{max(config.fractions):g}"]["head_cm"]["mean"]
    if "sim" in out["arms"]:
        out["sim_over_real"] = out["arms"]["sim"]["0"]["head_cm"]["mean"] / full
    out["equivalent_real_fraction"] = {
        f: equivalent_fraction(v["head_cm"]["mean"], config.fractions,
                               [real[f"{g:g}"]["head_cm"]["mean"] for g in config.fractions])
        for f, v in out["arms"].get("finetune", {}).items()}
    return out


def by_fit(reports: list[dict], others: list[dict], config: Config, results: dict) -> dict:
    """The sim-only Head error of every fit on the same folds, with its ratio to real only
    (where the real arm ran) and, per seed, for paired comparisons."""
    out = {}
    for fit in config.fits:
        cell = [r for r in [*reports, *others] if r["arm"] == "sim" and r.get("fit") == fit]
        out[fit] = {"head_cm": mean_std([r["head_cm"] for r in cell]),
                    "head_cm_by_seed": {str(r["seed"]): r["head_cm"] for r in cell}}
        if "real" in results["arms"]:
            real = results["arms"]["real"][f"{max(config.fractions):g}"]["head_cm"]["mean"]
            out[fit]["sim_over_real"] = out[fit]["head_cm"]["mean"] / real
    return out


def by_range(sims: list[dict], chosen: dict[tuple[str, int], dict], config: Config) -> dict:
    """Per fit, the `randomize` candidates' sim-only models: which each seed chose (on its
    fold's real validation block) and each candidate's Head error there and on the test
    block."""
    out = {}
    for fit in dict.fromkeys(r["fit"] for r in sims):
        cells = {r: [o for o in sims if o["fit"] == fit and o["randomize"] == r]
                 for r in config.candidates}
        out[fit] = {
            "chosen_by_seed": {str(s): c["randomize"] for (f, s), c in chosen.items()
                               if f == fit},
            "candidates": {r: {
                "select_head_cm": mean_std([o["select_head_cm"] for o in c]),
                "head_cm": mean_std([o["head_cm"] for o in c]),
                "select_head_cm_by_seed": {str(o["seed"]): o["select_head_cm"] for o in c},
                "head_cm_by_seed": {str(o["seed"]): o["head_cm"] for o in c}}
                for r, c in cells.items()}}
    return out


def by_ablation(reports: list[dict], chosen: dict[tuple[str, int], dict], config: Config
                ) -> dict:
    """Per switched-off group, the sim-only Head error and its difference to the lab's own
    sim model on the same seed, averaged to each fold (seeds s and s + folds share one) with
    the mean and 95 % interval over the folds, corrected for the training data they share
    (Nadeau-Bengio; none where no seed's profile held the group)."""
    lab = {s: r["head_cm"] for (f, s), r in chosen.items() if f == config.fits[0]}
    out = {}
    for group in config.ablate:
        cell = [r for r in reports if r["ablate"] == group]
        by_fold: dict[int, list[float]] = {}
        for r in cell:
            by_fold.setdefault(fold_of(r["seed"] - config.seed, config.folds), []).append(
                r["head_cm"] - lab[r["seed"]])
        out[",".join(group)] = {
            "head_cm": mean_std([r["head_cm"] for r in cell]),
            "head_cm_by_seed": {str(r["seed"]): r["head_cm"] for r in cell},
            "minus_lab": paired_interval([float(np.mean(d)) for d in by_fold.values()],
                                         cv_ratio(config.folds))}
    return out


def equivalent_fraction(error: float, fractions: tuple[float, ...], errors: list[float]
                        ) -> float | None:
    """The share of real data a real-only model needs to reach `error`: linear in log share
    between the measured fractions; None outside them (better than all of it, or worse than the
    smallest share)."""
    errs = np.minimum.accumulate(np.asarray(errors, float))    # more data never hurts
    if error < errs[-1] or error > errs[0]:
        return None
    i = int(np.searchsorted(-errs, -error))                   # first index with errs <= error
    if i == 0:
        return float(fractions[0])
    logf = np.log(np.asarray(fractions, float))
    e0, e1 = errs[i - 1], errs[i]
    w = (e0 - error) / (e0 - e1)
    return float(np.exp(logf[i - 1] + w * (logf[i] - logf[i - 1])))


def summary_lines(results: dict) -> list[str]:
    lines = []
    for arm, per in results["arms"].items():
        for f, v in per.items():
            h = v["head_cm"]
            share = "" if arm == "sim" else f" at {float(f) * 100:.0f} % real"
            lines.append(f"{arm:<9}{share:<14} Head {h['mean']:.2f} ± {h['std']:.2f} cm "
                         f"({h['n']} seeds)")
    for fit, ranges in results.get("ranges", {}).items():
        counts = Counter(ranges["chosen_by_seed"].values())
        lines.append(f"--randomize chosen per fold ({fit}): " + ", ".join(
            f"{Path(r).name} {n}x" for r, n in counts.most_common()))
    for tuned in TUNED:
        for arm, shares in results.get(tuned.table, {}).items():
            for f, cell in shares.items():
                counts = Counter(cell["chosen_by_seed"].values())
                lines.append(f"{arm} at {float(f) * 100:.0f} % real, {tuned.label} chosen per "
                             "seed: " + ", ".join(f"{w:g} {n}x" for w, n in counts.most_common()))
    for name, cell in results.get("ablations", {}).items():
        d = cell["minus_lab"]
        if d["mean"] is None:
            lines.append(f"without {name}: not in the lab's profile, nothing switched off")
            continue
        spread = "" if d["low"] is None else f" [{d['low']:+.2f}, {d['high']:+.2f}]"
        lines.append(f"without {name}: Head {d['mean']:+.2f} cm{spread} against the lab's "
                     f"({d['n']} folds)")
    if "sim_over_real" in results:
        lines.append(f"sim only / real only (100 %): {results['sim_over_real']:.2f}x")
    for f, g in results.get("equivalent_real_fraction", {}).items():
        worth = ("outside the measured range" if g is None
                 else f"worth {g * 100:.0f} % real-only")
        lines.append(f"fine-tuned on {float(f) * 100:.0f} % real: {worth}")
    return lines
