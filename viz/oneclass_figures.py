"""Figures and tables of `experiment oc` (matplotlib, Agg); every file written atomically."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import torch  # noqa: E402

from estimators.oneclass import train as T  # noqa: E402
from estimators.oneclass.methods import METHODS, flow_magnitude  # noqa: E402
from estimators.oneclass.model import OCModel  # noqa: E402
from macrostate_mj.core.io import atomic_path, write_text_atomic  # noqa: E402
from macrostate_mj.formats.hsants import AntFlowData, load_images, sample_file  # noqa: E402
from viz import gradcam as gc  # noqa: E402
from viz.figures import save_png

LABELS = {"ofw": "OFW", "dcae": "DCAE", "ocsvm": "OC-SVM", "dsvdd": "DSVDD", "gen": "GEN",
          "ngen": "N-GEN", "iogen": "IO-GEN"}
# The dissertation's Tables 4.1 and 4.2 (mean ± std over its 3 splits), printed beside ours
DISSERTATION_41 = {1: "0.760 ± 0.016", 2: "0.786 ± 0.009", 4: "0.787 ± 0.008"}
DISSERTATION_42 = {"ofw": "0.506", "dcae": "0.506 ± 0.002", "ocsvm": "0.523 ± 0.004",
                   "dsvdd": "0.762 ± 0.013", "gen": "0.587 ± 0.032", "ngen": "0.699 ± 0.006",
                   "iogen": "0.786 ± 0.009"}


def flow_weight_figure(path: Path, day: np.ndarray, w: np.ndarray, unstable: np.ndarray) -> None:
    """Fig 4.7: weights scaled to [0, 1] by min and 99.5th percentile (outliers left out)."""
    lo, hi = np.min(w), np.percentile(w, 99.5)
    scaled = np.clip((w - lo) / max(hi - lo, 1e-12), 0, 1)
    fig, ax = plt.subplots(figsize=(9, 3))
    ax.plot(day[~unstable], scaled[~unstable], ".", ms=2, color="tab:blue", label="stable")
    ax.plot(day[unstable], scaled[unstable], ".", ms=4, color="tab:orange", label="unstable")
    ax.axvline(0, color="red")
    ax.set(xlabel="day (gamergates removed at 0)", ylabel="optical-flow weight (scaled)")
    ax.legend(loc="upper right")
    save_png(fig, path, tight=True)


def bins_figure(path: Path, fig48: dict, marks: dict[str, str] | None = None) -> None:
    """Fig 4.8: AUC per time bin, mean ± std over the runs (splits and seeds), one line per
    method; "+" ("-") above a bin where IO-GEN beats (loses to) DSVDD with p < .05 in every
    run."""
    fig, ax = plt.subplots(figsize=(8, 4))
    for meth in METHODS:
        names = list(fig48[meth])
        mean = [np.nan if fig48[meth][b]["mean"] is None else fig48[meth][b]["mean"]
                for b in names]
        std = [0.0 if fig48[meth][b]["std"] is None else fig48[meth][b]["std"] for b in names]
        ax.errorbar(range(len(names)), mean, yerr=std, marker="o", capsize=3,
                    label=LABELS[meth])
    for i, b in enumerate(names):
        if marks and marks.get(b):
            ax.annotate(marks[b], (i, 0.97), ha="center", fontsize=12)
    ax.set_xticks(range(len(names)), names)
    ax.axhline(0.5, color="grey", lw=0.5)
    ax.set(ylabel="AUC", ylim=(0, 1))
    ax.legend(ncol=4, fontsize=8)
    save_png(fig, path, tight=True)


@torch.no_grad()
def model_figures(path49: Path, path410: Path, model: OCModel, x: np.ndarray, xs: np.ndarray,
                  xu: np.ndarray) -> dict:
    """Fig 4.9 (IO-GEN vs real flows) and Fig 4.10 (distance to c, classifier likelihood)."""
    gen = torch.Generator().manual_seed(model.cfg.seed + 1)
    g = model.generators["iogen"]
    fake = g(T.randn((6, 100), gen, next(g.parameters()))).cpu().numpy()
    real = x[np.random.default_rng(model.cfg.seed).choice(len(x), 6, replace=False)]
    fig, axes = plt.subplots(4, 6, figsize=(9, 6.4))
    for row, (data, name) in enumerate(((fake, "IO-GEN"), (real, "real"))):
        for j in range(6):
            for c in range(2):  # H and V of the first flow pair, each normalised alone
                ax = axes[2 * row + c, j]
                ax.imshow(data[j, c], cmap="jet")
                ax.set_axis_off()
                ax.set_title(f"{name} {'HV'[c]}", fontsize=7)
    save_png(fig, path49, tight=True)

    codes = {"stable test": T.encode(model.dsvdd, torch.from_numpy(xs)),
             "unstable": T.encode(model.dsvdd, torch.from_numpy(xu))}
    for kind in ("iogen", "gen"):
        if kind in model.generators:
            codes[LABELS[kind]] = T.generated_codes(model.generators[kind], model.dsvdd, 512, gen)
    dist = {k: ((v - model.c) ** 2).sum(1).sqrt().numpy() for k, v in codes.items()}
    scale = float(dist["stable test"].max())
    like = {k: torch.sigmoid(model.classifiers["iogen"](v)).numpy() for k, v in codes.items()}
    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 3.5), constrained_layout=True)
    a.boxplot([d / scale for d in dist.values()], tick_labels=list(dist))
    a.set(ylabel="distance to c (÷ max stable)")
    b.boxplot(list(like.values()), tick_labels=list(like))
    b.set(ylabel="IO-GEN classifier: P(unstable)")
    save_png(fig, path410, tight=True)
    return {"median_distance": {k: float(np.median(v)) for k, v in dist.items()},
            "median_likelihood": {k: float(np.median(v)) for k, v in like.items()}}


def gradcam_outputs(folder: Path, model: OCModel, d: AntFlowData, xs: np.ndarray,
                    stable_ids: list[int], xu: np.ndarray, n: int, m: int) -> dict:
    """Grad-CAM of the IO-GEN classifier on the n most 'unstable' samples: raw and top-5 % PNG
    overlays on the img frames, an MP4 of the top-5 % frames, the same top-5 % maps on n stable
    test samples beside them, and the maps as .npy. On a simulated colony (one with
    `boxes.csv`), the maps scored against its true duel and bite boxes (`score_boxes`)."""
    folder.mkdir(exist_ok=True)
    maps = gc.upsample(gc.gradcam(model.dsvdd, model.classifiers["iogen"], xu))
    top = gc.top_share(maps)  # position-wise minimum over all unstable samples
    order = np.argsort(-model.score("iogen", xu))[:n]
    source = d.unstable_dir or d.root / "Unstable"
    ids = [d.unstable_ids[i] for i in order]
    if all((source / sample_file("img", i, 0)).is_file() for i in ids):  # a dev set has none
        imgs = load_images(source, ids, m)
        gc.write_png(folder / "overlay_raw.png", gc.overlay_grid(imgs, maps[order]))
        gc.write_png(folder / "overlay_top5.png", gc.overlay_grid(imgs, top[order]))
        frames = [gc.overlay(f, top[i]) for i, fs in zip(order, imgs, strict=True) for f in fs]
        gc.write_mp4(folder / "overlay_top5.mp4", [np.kron(f, np.ones((4, 4, 1), np.uint8))
                                                   for f in frames], fps=2.0)
        _stable_beside(folder / "overlay_stable_unstable.png", model, d, xs, stable_ids,
                       maps[order], imgs, n, m)
    with atomic_path(folder / "heatmaps.npy") as tmp, open(tmp, "wb") as fh:
        np.save(fh, maps)
    out = {"samples": [int(d.unstable_ids[i]) for i in order],
           "peak_rc": [list(map(int, np.unravel_index(np.argmax(maps[i]), maps[i].shape)))
                       for i in order]}
    boxes = read_boxes(d.root / "boxes.csv", m)
    if boxes is not None:   # a simulated colony: score Grad-CAM where the seed judged by eye
        out |= score_boxes(maps, xu, d, [boxes.get(i, []) for i in d.unstable_ids],
                           model.cfg.seed)
    return out


def _stable_beside(path: Path, model: OCModel, d: AntFlowData, xs: np.ndarray,
                   stable_ids: list[int], unstable_maps: np.ndarray, unstable_imgs: np.ndarray,
                   n: int, m: int) -> None:
    """Top rows: the n most unstable samples; bottom rows: n stable test samples spread over
    the recording; every map shown as §4.7.4 shows them (position-wise minimum over all the
    shown samples subtracted, each map's top 5 % coloured)."""
    pick = np.unique(np.linspace(0, len(stable_ids) - 1, n).round().astype(int))
    if not all((d.root / "Stable" / sample_file("img", stable_ids[i], 0)).is_file()
               for i in pick):
        return
    stable_maps = gc.upsample(gc.gradcam(model.dsvdd, model.classifiers["iogen"], xs[pick]))
    imgs = np.concatenate([unstable_imgs,
                           load_images(d.root / "Stable", [stable_ids[i] for i in pick], m)])
    gc.write_png(path, gc.overlay_grid(imgs, gc.top_share(np.concatenate([unstable_maps,
                                                                          stable_maps]))))


def score_boxes(maps: np.ndarray, xu: np.ndarray, d: AntFlowData, boxes: list[list],
                seed: int, resamples: int = 2000) -> dict:
    """Where the top 5 % of a map lands against the true duel and bite boxes, pooled and per
    day bin, each with a bootstrap interval over samples (`gc.box_counts`): `boxes_hit`, the
    share of boxes one of those pixels touches (the pointing game as §4.7.4's displays invite
    it), and `pixels_on_boxes`, the share of those pixels inside a box (which scattering
    cannot win; a flat map misses with all its pixels, and `flat_gradcam_maps` counts
    Grad-CAM's). For Grad-CAM as computed and as §4.7.4 displays it (position-wise
    minimum over the samples subtracted), against maps that know nothing of the model: the
    flow magnitude, a centre prior and uniform noise (the chance level). Also the peak-only
    pointing game."""
    rng = np.random.default_rng(seed)
    shape = maps.shape[1:]
    kinds = {"gradcam": maps, "gradcam_display": maps - maps.min(axis=0, keepdims=True),
             "flow_magnitude": flow_magnitude(xu).sum(axis=1),   # 64 x 64 like the maps
             "centre_prior": gc.centre_prior(len(maps), shape),
             "random": rng.random((len(maps), *shape)).astype(np.float32)}
    bins = np.array(d.time_bin(d.unstable_ids), dtype=object)

    def table(counts: np.ndarray) -> dict:
        return {"all": gc.hit_share(counts, rng, resamples),
                "bins": {b: gc.hit_share(counts[bins == b], rng, resamples) for b in d.bins}}

    top5 = {}
    for name, kind in kinds.items():
        hit, on = gc.box_counts(kind, boxes)
        top5[name] = {"boxes_hit": table(hit), "pixels_on_boxes": table(on)}
    return {"top5": top5,
            "flat_gradcam_maps": int(sum(1 for heat, b in zip(maps, boxes, strict=True)
                                         if b and not heat.max() > heat.min())),
            "pointing_game": {"gradcam": gc.pointing_game(maps, boxes),
                              "flow_magnitude_baseline": gc.pointing_game(kinds["flow_magnitude"],
                                                                          boxes),
                              "chance": gc.box_share(boxes, shape),
                              "samples_with_boxes": sum(1 for b in boxes if b)}}


def read_boxes(path: Path, m: int) -> dict[int, list[tuple[float, float, float, float]]] | None:
    """`boxes.csv` of a simulated colony (sample_id, k, x, y, w, h in 64 x 64 sample pixels)
    -> boxes per sample over the flow pairs k < m a model of m pairs sees; None for data
    without ground truth (real)."""
    if not path.exists():
        return None
    rows = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    boxes: dict[int, list[tuple[float, float, float, float]]] = {}
    for sid, k, x, y, w, h in rows:
        if k < m:
            boxes.setdefault(int(sid), []).append((x, y, w, h))
    return boxes


def write_tables(path: Path, t41: dict, t42: dict, f48: dict, n_unstable: int,
                 marks: dict[str, str] | None = None, on_test: dict | None = None) -> None:
    def fmt(v: dict) -> str:
        return "n/a" if v["mean"] is None else f"{v['mean']:.3f} ± {v['std']:.3f}"

    lines = [f"Unstable samples scored: {n_unstable}.", "", "## Table 4.1 (IO-GEN AUC by m)", "",
             "| m | AUC | dissertation |", "|---|---|---|",
             *[f"| {m} | {fmt(v)} | {DISSERTATION_41.get(int(m), '')} |" for m, v in t41.items()],
             "", "## Table 4.2 (AUC, all unstable)", "", "| method | AUC | dissertation |",
             "|---|---|---|",
             *[f"| {LABELS[k]} | {fmt(v)} | {DISSERTATION_42[k]} |" for k, v in t42.items()], "",
             "## Fig 4.8 (AUC by time bin)", ""]
    names = list(next(iter(f48.values())))
    lines += ["| method | " + " | ".join(names) + " |", "|---" * (len(names) + 1) + "|"]
    lines += [f"| {LABELS[k]} | " + " | ".join(
        fmt(v[b]) + (f" {marks[b]}" if k == "iogen" and marks and marks.get(b) else "")
        for b in names) + " |" for k, v in f48.items()]
    lines += ["", "IO-GEN marked + (-) where it beats (loses to) DSVDD with p < .05 in every "
              "run, split and seed (paired stratified bootstrap, 2,000 resamples)."]
    if on_test:
        lines += ["", "## Checkpoint chosen on test data (research; never used above)", "",
                  "| method | kept (stable-only selection) | best epoch on test |", "|---|---|---|",
                  *[f"| {LABELS[k]} | {fmt(v['kept_auc'])} | {fmt(v['best_auc'])} |"
                    for k, v in on_test.items()], "",
                  "The epoch of DSVDD and of each classifier that scores best on the test and "
                  "unstable samples themselves, as the published code chose its checkpoints."]
    write_text_atomic(path, "\n".join(lines) + "\n")
