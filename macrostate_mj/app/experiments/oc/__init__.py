"""`experiment oc`: Table 4.1 (m = 1, 2, 4), Table 4.2 and Fig 4.8 (mean ± std over the splits
and seeds), Fig 4.7 (optical-flow weight over time), Fig 4.9/4.10 and Grad-CAM (Fig 4.11–4.13:
heatmaps always, overlays only where the unstable samples carry their img frames; a dev set of
flows has none).

Each (m, split, seed) is a cached task (`OUT/cache/oc-run/<key>/report.json`) keyed by the
config, the run's coordinates and the bytes of its inputs; its training stages are cached beside
it (`oc-dcae`, `oc-dsvdd`, ...), so a killed run resumes from its last finished stage and a rerun
with more seeds or splits trains only the new runs."""

from __future__ import annotations

import json
import secrets
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import typer

from estimators.oneclass.methods import METHODS, flow_weight
from estimators.oneclass.metrics import auc_report, paired_report, roc_auc
from estimators.oneclass.model import OCModel, Probe, fit
from estimators.oneclass.train import OCConfig
from macrostate_mj.app.experiments import Parallel, Progress, register
from macrostate_mj.app.experiments.oc.record import Results
from macrostate_mj.app.params import (
    MAX_WORKERS,
    Choice,
    Count,
    Device,
    InputDir,
    Positive,
    Precision,
    Seed,
    Switch,
    flag,
)
from macrostate_mj.core.cache import run_tasks, task_key
from macrostate_mj.core.errors import UserError
from macrostate_mj.core.parallel import torch_threads
from macrostate_mj.core.paths import real_dataset
from macrostate_mj.core.stats import mean_std
from macrostate_mj.formats.hsants import AntFlowData, open_dataset

REAL_DATA = ("hsants", "hsants-dev")   # the published datasets it reads (`data fetch NAME`)
PRODUCTS = ["results.json", "tables.md", "fig4_7_flow_weight.png", "fig4_8_bins.png",
            "fig4_9_flows.png", "fig4_10_distances.png", "gradcam"]




QUICK_SCALE = 0.03      # the quick profile's share of every epoch and step count


def _integers(flag_name: str) -> Callable[[str], tuple[int, ...]]:
    def parse(text: str) -> tuple[int, ...]:
        try:
            return tuple(int(v) for v in text.split(","))
        except ValueError:
            raise UserError(f"{flag_name} takes comma-separated integers, e.g. 1,2,3") from None
    return parse


@dataclass(frozen=True)
class Config:
    data: Path = field(default_factory=lambda: real_dataset("OpticalFlows_HsAnts"),
                       metadata=flag(InputDir(None, "Dataset folder (real or simulated)."),
                                     default=...))
    splits: tuple[int, ...] = field(default=(1, 2, 3), metadata=flag(
        typer.Option(None, help="Comma-separated splits."), parse=_integers("--splits"), type=str))
    ms: tuple[int, ...] = field(default=(1, 2, 4), metadata=flag(
        typer.Option(None, help="Comma-separated m values (flow pairs per input, Table 4.1)."),
        parse=_integers("--ms"), type=str))
    config: OCConfig = OCConfig()
    max_train: int | None = None  # subsample the stable train split (quick runs only)
    gradcam_samples: int = 6
    # unstable samples held apart (a dev set), else data/Unstable
    unstable: Path | None = field(default=None, metadata=flag(InputDir(
        None, "Score these unstable samples instead of DATA/Unstable (a dev set; ids of the "
        "full colony, so bins hold)."), default=None, shown="DATA/Unstable"))
    # training seeds per (m, split): config.seed, config.seed + 1 ...
    seeds: int = field(default=1, metadata=flag(Count(
        None, "Training seeds per (m, split): seed, seed+1, ... (tables give mean ± std over "
        "splits and seeds).")))
    # research: score test data every epoch (`selection_on_test`)
    probe: bool = field(default=False, metadata=flag(Switch(
        False, "Research only: score the test and unstable samples after every DSVDD and "
        "classifier epoch and report what choosing the checkpoint on them would score (the "
        "published code's protocol); never used to select. Runs do not resume mid-run.",
        "--probe-test/--no-probe-test")))

    @property
    def seed(self) -> int:
        return self.config.seed


PROFILES = {
    # what `experiment all` runs: Table 4.1 (m = 1, 2, 4) and Table 4.2 / Fig 4.8 (m = 2) on
    # the dev set of real unstable flows, seed 1: the committed results/oc_dev_table41, whose
    # m = 2 runs are results/oc_dev_dsvdd160_3x3's seed-1 third
    "full": Config(unstable=real_dataset("OpticalFlows_HsAnts-dev") / "Unstable",
                   config=OCConfig(seed=1)),
    "quick": Config(config=OCConfig().scaled(QUICK_SCALE), max_train=200)}
PARALLEL = Parallel("one (m, split, seed) run each")
# the one-class recipe (`OCConfig`): the command builds it from these, whatever the profile's
FLAGS = {
    "seed": Seed(0, "The first training seed (whatever the profile: the recipe flags build "
                 "the recipe)."),
    "recipe": Choice("short", "Epoch and step counts: short (for a 2-core CPU) or published "
                     "(the published code's; hours on a CPU).", ("short", "published")),
    "epoch_scale": Positive(1.0, "Scale every epoch/step count of the recipe (--quick scales "
                            f"it by a further {QUICK_SCALE}).", "--epoch-scale"),
    "settings": typer.Option([], "--set", help="Research: NAME=VALUE on top of the recipe "
                             "(e.g. cls_epochs=40); repeatable."),
    "threads": Count(None, "torch CPU threads per run (default: the cores over the workers, at "
                     "most 2, so that workers do not fight over cores; results repeat for "
                     "equal threads).", max=MAX_WORKERS, show_default=False),
    "device": Device(),
    "precision": Precision(),
}


def configure(config: Config, changes: dict, *, profile: str, workers: int, seed: int,
              recipe: str, epoch_scale: float, settings: list[str], threads: int | None,
              device: str, precision: str) -> dict:
    """The command's recipe flags as the config's `OCConfig`."""
    scale = epoch_scale * (QUICK_SCALE if profile == "quick" else 1.0)
    recipe_config = OCConfig.recipe(recipe, seed=seed, threads=threads or torch_threads(workers),
                                    device=device, precision=precision)
    return {"config": recipe_config.scaled(scale).overridden(settings)}


def validate(config: Config) -> None:
    """The dataset holds the splits and sub-frames asked for (before the folder is claimed)."""
    data = open_dataset(config.data)
    for k in config.splits:
        data.split(k)
    for m in config.ms:
        if not 1 <= m <= data.subframes:
            raise UserError(f"--ms has m = {m} but {config.data} has {data.subframes} "
                            "sub-frames per sample")
RUN_VERSION = 1    # bump when a run's report changes for the same inputs
DRIVER_MARK = ".driver"   # a folder in the stages folder: its file proves a worker sees it


def missing(exp: Config) -> str | None:
    """The input this run cannot start without, if it is absent (`experiment all` skips it)."""
    if not exp.data.is_dir():
        return f"the ant flow dataset {exp.data}"
    if exp.unstable is not None and not exp.unstable.is_dir():
        return (f"the unstable samples {exp.unstable} (`experiment oc --data DIR` scores "
                "DIR/Unstable instead)")
    return None


def _inputs(d: AntFlowData, split: int, m: int, max_train: int | None, seed: int):
    train, test = d.split(split)
    if max_train and len(train) > max_train:
        train = sorted(np.random.default_rng(seed).choice(train, max_train, replace=False))
    return (d.load("Stable", train, m), d.load("Stable", test, m),
            d.load("Unstable", d.unstable_ids, m))


def significance_marks(tests: list[dict], names: tuple[str, ...], alpha: float = 0.05
                       ) -> dict[str, str]:
    """Per bin (and "all"): "+" where IO-GEN beats DSVDD with p < alpha in every run (split and
    seed), "-" where it loses so in every run, "" otherwise (paired stratified bootstrap per
    run)."""
    def mark(per_split: list[dict | None]) -> str:
        if any(t is None for t in per_split):
            return ""
        if all(t["p"] < alpha and t["diff"] > 0 for t in per_split):
            return "+"
        if all(t["p"] < alpha and t["diff"] < 0 for t in per_split):
            return "-"
        return ""

    return {"all": mark([t["all"] for t in tests]),
            **{b: mark([t["bins"][b] for t in tests]) for b in names}}


Kept = tuple[OCModel, np.ndarray, np.ndarray, np.ndarray]   # a model and its x, xs, xu


class RunTask:
    """One (m, split, seed) as a cached task: its AUC reports (all a rerun needs), keyed by the
    config, the run's coordinates and the bytes of its inputs. It trains in a worker with its
    stages cached in `stages` (where the figures' model is reloaded from), and loads its
    inputs there again rather than carrying them (150 MB of flows): on a Ray node, the data and
    `stages` must be the driver's own folders, on a shared file system, which `seen` checks by
    a mark the driver leaves in `stages`."""

    stage: ClassVar[str] = "oc-run"
    version: ClassVar[int] = RUN_VERSION

    def __init__(self, exp: Config, m: int, split: int, seed: int, main_m: int,
                 stages: Path, mark: str = ""):
        self.exp, self.m, self.split, self.seed, self.main_m = exp, m, split, seed, main_m
        self.stages, self.mark = stages, mark
        self._key: str | None = None

    def seen(self) -> None:
        """Refuse, in one line, a node that does not see the driver's folders."""
        if self.mark and not (self.stages / DRIVER_MARK / self.mark).is_file():
            raise UserError(f"experiment oc: a worker does not see {self.stages} (or the flows "
                            f"in {self.exp.data}): on a Ray cluster, --out and the data must sit "
                            "on a file system every node shares, at the same paths")

    @property
    def name(self) -> str:
        return f"m{self.m}_split{self.split}_s{self.seed}"

    def inputs(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return _inputs(_dataset(self.exp), self.split, self.m, self.exp.max_train, self.seed)

    def key(self) -> str:
        if self._key is None:
            self._key = task_key(self.stage, self.version, {
                "config": replace(self.exp.config, m=self.m, seed=self.seed),
                "split": self.split, "probe": self.exp.probe, "main": self.m == self.main_m},
                self.inputs())
        return self._key

    def compute(self) -> dict[str, bytes]:
        self.seen()
        report, _ = _train(_dataset(self.exp), self.exp, self.inputs(), self.m, self.split,
                           self.seed, self.main_m, self.stages)
        return {"report.json": json.dumps(report).encode()}


def _dataset(exp: Config) -> AntFlowData:
    d = open_dataset(exp.data)
    return d if exp.unstable is None else d.with_unstable(exp.unstable)


def _train(d: AntFlowData, exp: Config, inputs: tuple[np.ndarray, ...], m: int, split: int,
           seed: int, main_m: int, stages: Path) -> tuple[dict, Kept]:
    bins, names = d.time_bin(d.unstable_ids), tuple(d.bins)
    x, xs, xu = inputs
    methods = METHODS if m == main_m else ("iogen",)
    cfg = replace(exp.config, m=m, seed=seed)
    probe = Probe(np.concatenate([xs, xu])) if exp.probe else None
    model = fit(x, methods, cfg, stages_dir=None if probe else stages,  # resumes from its last
                probe=probe)                            # stage (a probe watches them all)
    scores = {meth: (model.score(meth, xs), model.score(meth, xu)) for meth in methods}
    report = {meth: auc_report(*scores[meth], bins, names) for meth in methods}
    if probe is not None:
        report["selection_on_test"] = selection_on_test(probe, model.history, len(xs))
    if m == main_m:   # Fig 4.8's marks: IO-GEN against DSVDD on the same samples
        report["iogen_vs_dsvdd"] = paired_report(*scores["iogen"], *scores["dsvdd"], bins,
                                                 names, seed=seed)
    return report, (model, x, xs, xu)


def selection_on_test(probe: Probe, history: dict[str, list[float]], n_stable: int) -> dict:
    """Per watched method: the AUC on the probe's inputs (stable test first, then unstable)
    after every epoch; the epoch kept by stable-only selection, and the one a choice on these
    test samples would keep (the published code's protocol), with their AUCs."""
    out = {}
    for meth, curve in probe.curves.items():
        aucs = [roc_auc(s[:n_stable], s[n_stable:]) for s in curve]
        val = history["dsvdd_val" if meth == "dsvdd" else f"cls_{meth}_val"]
        kept, best = int(np.argmin(val)), int(np.argmax(aucs))
        out[meth] = {"auc_by_epoch": aucs, "kept_epoch": kept, "kept_auc": aucs[kept],
                     "best_epoch": best, "best_auc": aucs[best]}
    return out


@register
def run(exp: Config, out: Path, progress: Progress) -> list[str]:
    """Train and score every (m, split, seed); summarise over splits and seeds; draw the
    figures and tables into `out`. A rerun resumes from the cached runs and stages."""
    from viz import oneclass_figures as figures

    d = _dataset(exp)
    bins, names = d.time_bin(d.unstable_ids), tuple(d.bins)
    main_m = 2 if 2 in exp.ms else exp.ms[0]
    seeds = range(exp.config.seed, exp.config.seed + exp.seeds)
    mark = secrets.token_hex(8)         # what a worker must find in the stages folder
    (progress.cache.root / DRIVER_MARK).mkdir(parents=True, exist_ok=True)
    (progress.cache.root / DRIVER_MARK / mark).touch()
    tasks = [RunTask(exp, m, split, seed, main_m, progress.cache.root, mark)
             for m in exp.ms for split in exp.splits for seed in seeds]
    runs: dict[str, dict] = {}
    cached = 0
    with progress.stage("runs"):
        for outcome in run_tasks(progress.cache, tasks, progress.workers, progress.ray):
            runs[outcome.task.name] = json.loads((outcome.folder / "report.json").read_text())
            cached += outcome.cached
            progress.report("runs", len(runs), len(tasks), cached)
    runs = {t.name: runs[t.name] for t in tasks}           # in task order, whatever finished first
    with progress.stage("figures_model"):  # the first run's model, from its cached stages
        first = next(t for t in tasks if t.m == main_m)
        keep = first.name, _train(d, exp, first.inputs(), main_m, first.split, first.seed,
                                  main_m, progress.cache.root)[1]

    def over(m: int, get: Callable[[dict], Any]) -> list:
        return [get(runs[f"m{m}_split{k}_s{s}"]) for k in exp.splits for s in seeds]

    table41 = {m: mean_std(over(m, lambda r: r["iogen"]["auc_all"])) for m in exp.ms}
    table42 = {meth: mean_std(over(main_m, lambda r, meth=meth: r[meth]["auc_all"]))
               for meth in METHODS}
    fig48 = {meth: {b: mean_std(over(main_m, lambda r, meth=meth, b=b: r[meth]["auc_bins"][b]))
                    for b in names} for meth in METHODS}
    marks = significance_marks(over(main_m, lambda r: r["iogen_vs_dsvdd"]), names)
    results = {"table4_1_iogen_auc_by_m": table41, "fig4_8_iogen_vs_dsvdd_marks": marks,
               f"table4_2_auc_m{main_m}": table42,
               f"fig4_8_auc_by_bin_m{main_m}": fig48, "runs": runs,
               "n_unstable": len(d.unstable_ids), "n_unstable_by_bin":
                   {b: bins.count(b) for b in names}}
    if exp.probe:
        results["selection_on_test"] = {
            meth: {k: mean_std(over(main_m, lambda r, meth=meth, k=k:
                                     r["selection_on_test"][meth][k]))
                   for k in ("kept_auc", "best_auc")}
            for meth in ("dsvdd", "gen", "ngen", "iogen")}
    weights = _flow_weights(d)
    figures.flow_weight_figure(out / PRODUCTS[2], *weights)
    figures.bins_figure(out / PRODUCTS[3], fig48, marks)
    results["figures_run"], (model, x, xs, xu) = keep
    model = model.to("cpu")
    results["fig4_10"] = figures.model_figures(out / PRODUCTS[4], out / PRODUCTS[5], model, x, xs,
                                               xu)
    results["gradcam"] = figures.gradcam_outputs(out / PRODUCTS[6], model, d, xs,
                                                 d.split(first.split)[1], xu,
                                                 exp.gradcam_samples, main_m)
    figures.write_tables(out / PRODUCTS[1], table41, table42, fig48, len(d.unstable_ids), marks,
                         results.get("selection_on_test"))
    Results.of(results, "experiment oc").write(out)
    return [(out / PRODUCTS[1]).read_text()]


def _flow_weights(d: AntFlowData) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(day position, weight, is_unstable) with m = 1 for every sample, for Fig 4.7."""
    ws = flow_weight(d.load("Stable", d.stable_ids, 1))
    wu = flow_weight(d.load("Unstable", d.unstable_ids, 1))
    n = len(d.stable_ids)
    day_s = -2.0 + 2.0 * np.arange(n) / n  # D-2 .. D-0 over the stable recording
    first = min(a for a, _ in d.bins.values())
    end = max(e for _, e in d.bins.values())
    day_u = 18.0 * (np.asarray(d.unstable_ids) - first) / max(1, end - first)  # D+0 .. D+18
    return (np.concatenate([day_s, day_u]), np.concatenate([ws, wu]),
            np.concatenate([np.zeros(n, bool), np.ones(len(wu), bool)]))
