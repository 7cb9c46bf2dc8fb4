"""`experiment oc`'s tables, numbers and claims' figures, read through its record."""

from __future__ import annotations

import re

from macrostate_mj.app.experiments.oc.record import Results
from macrostate_mj.app.results.claims import ALPHA
from macrostate_mj.app.results.sources import (
    record,
    source,
)
from macrostate_mj.core.evidence import ClaimsError, Figure, Q, Table


@source
def oc_marks(folder: str, sign: str) -> Q:
    """Fig 4.8's paired tests, IO-GEN against DSVDD over every run and bin: how many cells
    IO-GEN wins (`above`), loses (`below`) or neither (`level`) at p < .05."""
    runs = record(Results, folder).runs
    counts = {"above": 0, "below": 0, "level": 0}
    for run in runs.values():
        for test in run["iogen_vs_dsvdd"]["bins"].values():
            key = "level" if test["p"] >= ALPHA else ("above" if test["diff"] > 0 else "below")
            counts[key] += 1
    return Q(counts[sign], None, "d", f"of {sum(counts.values())} run-bins")


@source
def oc_table42(folder: str) -> Table:
    """Table 4.2: AUC on all unstable samples, mean ± std over the folder's runs."""
    data = record(Results, folder)
    rows = [["method", "AUC"]]
    for method, ms in data.table4_2_auc_m2.items():
        rows.append([method, f"{ms['mean']:.3f} ± {ms['std']:.3f}"])
    return rows


@source
def oc_fig48(folder: str) -> Table:
    """Fig 4.8: AUC by time bin, mean ± std over the folder's runs."""
    data = record(Results, folder).fig4_8_auc_by_bin_m2
    bins = list(next(iter(data.values())))
    order = sorted(bins, key=lambda b: int(re.findall(r"\d+", b)[0]))
    rows = [["method", *order]]
    for method, by_bin in data.items():
        rows.append([method, *[f"{by_bin[b]['mean']:.3f} ± {by_bin[b]['std']:.3f}"
                               for b in order]])
    return rows


@source
def oc_runs(folder: str) -> Table:
    """The runs behind a one-class folder: m, split, seed and each method's AUC."""
    runs = record(Results, folder).runs
    methods = list(next(iter(runs.values())))
    methods = [m for m in methods if m != "iogen_vs_dsvdd"]
    rows = [["run", *methods]]
    for name, run in runs.items():
        rows.append([name, *[f"{run[m]['auc_all']:.3f}" for m in methods]])
    return rows


@source
def oc_pairs(base: str, other: str) -> Table:
    """Two one-class folders on their common runs (m, split, seed): per method the AUC of
    each run in both, and the mean difference (other - base)."""
    a, b = (record(Results, f).runs for f in (base, other))
    shared = [r for r in a if r in b]
    methods = [m for m in a[shared[0]] if m in b[shared[0]] and m != "iogen_vs_dsvdd"]
    rows = [["method", *[f"{r}: {base} / {other}" for r in shared], "mean difference"]]
    for m in methods:
        pairs = [(a[r][m]["auc_all"], b[r][m]["auc_all"]) for r in shared]
        rows.append([m, *[f"{x:.3f} / {y:.3f}" for x, y in pairs],
                     f"{sum(y - x for x, y in pairs) / len(pairs):+.3f}"])
    return rows


def _share_ci(h: dict) -> str:
    return "" if h["share"] is None else (
        f"{100 * h['share']:.1f} ({100 * h['lo']:.1f} to {100 * h['hi']:.1f})")


@source
def gradcam_hits(folder: str) -> Table:
    """§4.7.4 scored on a simulated colony: per map, the share (%) of true duel/bite boxes its
    top 5 % touches and the share of its top 5 % on a box, all unstable samples with a box,
    with the bootstrap 95 % interval."""
    data = record(Results, folder).gradcam["top5"]
    rows = [["map", "boxes hit (%)", "top-5 % pixels on a box (%)"]]
    for name, kind in data.items():
        rows.append([name, _share_ci(kind["boxes_hit"]["all"]),
                     _share_ci(kind["pixels_on_boxes"]["all"])])
    return rows


@source
def gradcam_bins(folder: str, metric: str) -> Table:
    """One of `gradcam_hits`' measures (%) per day bin, with the samples each bin holds."""
    data = record(Results, folder).gradcam["top5"]
    first = next(iter(data.values()))[metric]["bins"]
    bins = sorted(first, key=lambda b: int(re.findall(r"\d+", b)[0]))
    rows = [["map", *bins]]
    for name, kind in data.items():
        rows.append([name, *[_share_ci(kind[metric]["bins"][b]) for b in bins]])
    rows.append(["samples", *[str(first[b]["samples"]) for b in bins]])
    return rows


def _oc_runs(folder: str, m: str) -> dict[str, dict]:
    runs_ = record(Results, folder).runs
    got = {key.split("_", 1)[1]: run for key, run in runs_.items()
           if key.startswith(f"m{m}_")}
    if not got:
        raise ClaimsError(f"results/{folder} has no m = {m} runs")
    return got


@source
def oc_auc(folder: str, method: str, m: str = "2") -> Figure:
    """Chapter 4: a one-class method's AUC per run (split × seed, paired across methods and m)."""
    return Figure.of({k: float(r[method]["auc_all"]) for k, r in _oc_runs(folder, m).items()
                      if method in r}, ".3f")


@source
def oc_auc_change(folder: str, method: str, m: str, base_m: str) -> Figure:
    """Chapter 4: a method's AUC at `m` minus at `base_m`, per run (paired by split and seed)."""
    a, b = (oc_auc(folder, method, k).values for k in (m, base_m))
    assert a is not None and b is not None
    return Figure.of({k: a[k] - b[k] for k in a if k in b}, ".3f")


@source
def oc_margin(folder: str) -> Figure:
    """Fig 4.8 per run: time bins where IO-GEN is significantly above DSVDD (p < .05) minus
    those where it is significantly below."""
    def margin(run: dict) -> float:
        bins = run["iogen_vs_dsvdd"]["bins"].values()
        return float(sum((t["p"] < ALPHA) * (1 if t["diff"] > 0 else -1) for t in bins))
    return Figure.of({k: margin(r) for k, r in _oc_runs(folder, "2").items()}, ".1f", "bins")

