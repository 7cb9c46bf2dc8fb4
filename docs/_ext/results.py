"""Numbers on the results pages, read from the committed `results/` files when the docs build.

A page never types a measured number. It names where the number lives:

- inline, the role ``{n}`json(srs_text/results.json, configs/passive/1.0000/head_cm, .1f)` ``;
- a table, the directive ``{results-table} srs(srs_text, all_predictions_cm)``;
- a chapter's claims, ``{claims} chapter3``: judged by `macrostate_mj.app.claims` (what
  `macrostate-mj claims` prints), from its `claims.toml`; ``{claims-summary}`` the rule and counts;
- a folder's provenance, ``{provenance} srs_text``: its command, kind, units and disclosures from
  `results/index.toml` (`macrostate_mj.app.provenance`), its date and machine from its manifest.

Every source's output is recorded per page in `_numbers.json` beside the built pages;
`tests/docs/test_docs.py` binds each number a results page shows to it (and each inline number
to its file, key and rounding), and fails on any other number it was not told to expect.
"""

from __future__ import annotations

import json
import math
import re
import statistics
import tomllib
from collections.abc import Callable
from dataclasses import dataclass
from datetime import UTC, datetime
from functools import cache
from pathlib import Path

from docutils import nodes
from docutils.parsers.rst import Directive
from sphinx.util.docutils import SphinxRole

from macrostate_mj.app.claims import Design, Figure, dig, parse
from macrostate_mj.app.provenance import read_index
from macrostate_mj.core.stats import mean_std

REPO = Path(__file__).resolve().parents[2]
RESULTS = REPO / "results"
NUMBERS = "_numbers.json"       # beside the built pages: every number each page was given


@dataclass(frozen=True)
class Q:
    """A measured quantity: a value, an optional spread, and how to print it."""

    value: float
    std: float | None = None
    fmt: str = ".2f"
    unit: str = ""

    def __str__(self) -> str:
        text = format(self.value, self.fmt)
        if self.std is not None:
            text += " ± " + format(self.std, self.fmt)
        return text + (f" {self.unit}" if self.unit else "")

    def __float__(self) -> float:
        return float(self.value)


Table = list[list]    # rows of cells: text, or a docutils node (a literal)
SOURCES: dict[str, Callable[..., object]] = {}


def source(fn: Callable[..., object]) -> Callable[..., object]:
    """Register a function pages may call by name."""
    SOURCES[fn.__name__] = fn
    return fn


@cache
def load(path: str) -> object:
    """A results file (JSON, or JSON lines as a list), once per build."""
    file = RESULTS / path
    if not file.is_file():
        raise ValueError(f"results/{path} does not exist")
    text = file.read_text()
    if file.suffix == ".jsonl":
        return [json.loads(line) for line in text.splitlines() if line.strip()]
    return json.loads(text)


@cache
def index() -> dict:
    """`results/index.toml`, checked (`macrostate_mj.app.provenance`), once per build."""
    return read_index(RESULTS)


def call(expression: str) -> object:
    """Evaluate a page's source expression (`macrostate_mj.app.claims.parse`)."""
    name, args = parse(expression)
    if name not in SOURCES:
        raise ValueError(f"not a results source: {expression!r} (one of {sorted(SOURCES)})")
    return SOURCES[name](*args)


# Sources of single quantities ------------------------------------------------------------------

@source
def json_value(path: str, keypath: str, fmt: str = ".2f", unit: str = "", scale: str = "1") -> Q:
    """One number of a JSON results file (times `scale`, e.g. 100 for a metre value in cm)."""
    return Q(float(dig(load(path), keypath)) * float(scale), None, fmt, unit)


SOURCES["json"] = json_value


@source
def meanstd(path: str, keypath: str, fmt: str = ".3f", unit: str = "") -> Q:
    """A `{mean, std}` object of a results file."""
    d = dig(load(path), keypath)
    return Q(float(d["mean"]), float(d["std"]), fmt, unit)  # type: ignore[index]


@source
def above(path: str, keypath: str, base: str, base_keypath: str, fmt: str = ".1f") -> Q:
    """How much (%) one `{mean, std}` figure's mean lies above another's (negative: below)."""
    a, b = (float(dig(load(f), k)["mean"])  # type: ignore[index]
            for f, k in ((path, keypath), (base, base_keypath)))
    return Q(100 * (a / b - 1), None, fmt, "%")


def _profile(folder: str) -> dict:
    """A run's recorded profile (`results.json`'s), empty where it keeps none."""
    if not (RESULTS / folder / "results.json").is_file():
        return {}
    return load(f"{folder}/results.json").get("profile") or {}  # type: ignore[union-attr]


def design(folders: list[str], seeds: list[str]) -> tuple[Design, dict[str, str]]:
    """What the seeds of `folders`' runs are as evidence, by the rule `macrostate-mj claims`
    judges by (`claims.Design`): the folder's units as `results/index.toml` declares them, or,
    for sim-to-real runs, which declare none, as their profiles record them: model i (seed
    `seed + i`) is tested on fold i mod `folds` (`experiment sim2real`), so the folds are the
    units, the seeds that share a fold (runs of other seeds on the same folds) are averaged to
    it, and the folds, which share most of their training data, are Nadeau-Bengio corrected.
    Elsewhere each seed is a unit. With it, each seed's key, where `Design.apply` finds its
    unit."""
    entries = [{k: v for k, v in index().get(f.split("/")[0], {}).items() if k in Design.KEYS}
               for f in folders]
    profiles = [_profile(f) for f in folders]
    if any(e.get("unit") for e in entries) or not all(p.get("folds") for p in profiles):
        if any(e != entries[0] for e in entries):
            raise ValueError(f"{', '.join(folders)}: runs of different units cannot pool")
        plan = Design.of(entries[0], "results/" + folders[0]) if entries[0] else Design("seed")
        return plan, {s: s for s in seeds}
    if len({int(p["folds"]) for p in profiles}) > 1:
        raise ValueError(f"{', '.join(folders)}: runs on different folds cannot pool")
    from macrostate_mj.app.experiments.sim2real import fold_of

    folds, fold = int(profiles[0]["folds"]), {}
    for p in profiles:
        first = int(p.get("seed") or 0)
        fold |= {str(first + i): fold_of(i, folds) for i in range(int(p.get("seeds") or folds))}
    if set(seeds) - set(fold):
        raise ValueError(f"{', '.join(folders)}: seeds {sorted(set(seeds) - set(fold))} are "
                         "not of these runs' profiles")
    nested = len({fold[s] for s in seeds}) < len(seeds)
    return (Design("fold", "seed" if nested else "", r"fold\d+" if nested else "", folds),
            {s: f"fold{fold[s]}/seed{s}" for s in seeds})


@dataclass(frozen=True)
class Paired:
    """A paired difference over the independent units of its runs (`design`): its mean and 95 %
    t interval over them, the units named beside it, and what it decides."""

    mean: float
    low: float
    high: float
    n: int
    units: str
    fmt: str = ".2f"
    unit: str = ""

    @classmethod
    def of(cls, differences: dict[str, float], folders: str | list[str], fmt: str = ".2f",
           unit: str = "") -> Paired:
        """Per-seed differences (keyed by seed) of `folders`' runs over their units: seeds that
        share a fold averaged to it and overlapping folds corrected (`claims.Design.apply`),
        the interval `claims.Figure.interval`'s: what the claims draw."""
        folders = [folders] if isinstance(folders, str) else folders
        plan, keys = design(folders, list(differences))
        fig = plan.apply(Figure.of({keys[s]: d for s, d in differences.items()}))
        ci = fig.interval()
        if ci is None:
            raise ValueError(f"{', '.join(folders)}: one {plan.unit}, no interval to draw")
        return cls(fig.mean, ci[0], ci[1], fig.n, f"{fig.n} {plan.says(fig.n)}", fmt, unit)

    def __str__(self) -> str:
        each = self.units.split(" ", 1)[1].split(",")[0].removesuffix("s")
        verdict = (f"equal on every {each}" if self.low == self.high == 0 else
                   "inconclusive" if self.low <= 0 <= self.high else "decided")
        f, u = self.fmt, f" {self.unit}" if self.unit else ""
        return (f"{self.mean:+{f}}{u} [{self.low:+{f}}, {self.high:+{f}}], {self.units}: "
                f"{verdict}")


@source
def paired(path: str, keypath: str, base_keypath: str, fmt: str = ".2f", unit: str = "") -> Paired:
    """Two per-seed lists (or {seed: value} maps, paired by seed) of one results file: the
    mean of their differences (the first minus the second) and its 95 % t interval over the
    folder's independent units (`Paired.of`: a sim-to-real run's folds). `path` may join
    several runs' files with `+` (other seeds of the same folds): their {seed: value} maps
    pool, a seed named twice refused, and seeds that share a fold are averaged to it."""
    runs = [load(p) for p in path.split("+")]
    a, b = (dig(runs[0], k) for k in (keypath, base_keypath))
    for run in runs[1:]:
        more = [dig(run, k) for k in (keypath, base_keypath)]
        if any(set(m) & set(have) for m, have in zip(more, (a, b), strict=True)):  # type: ignore[arg-type]
            raise ValueError(f"{path}: a seed appears in more than one run")
        a, b = {**a, **more[0]}, {**b, **more[1]}  # type: ignore[dict-item]
    if not isinstance(a, dict):
        a, b = dict(enumerate(a)), dict(enumerate(b))  # type: ignore[arg-type]
    folders = [str(Path(p).parent) for p in path.split("+")]
    return Paired.of({str(s): a[s] - b[s] for s in sorted(a, key=str)},  # type: ignore[index]
                     folders, fmt, unit)


@source
def oc_marks(folder: str, sign: str) -> Q:
    """Fig 4.8's paired tests, IO-GEN against DSVDD over every run and bin: how many cells
    IO-GEN wins (`above`), loses (`below`) or neither (`level`) at p < .05."""
    runs = dig(load(f"{folder}/results.json"), "runs")
    counts = {"above": 0, "below": 0, "level": 0}
    for run in runs.values():  # type: ignore[union-attr]
        for test in run["iogen_vs_dsvdd"]["bins"].values():
            key = "level" if test["p"] >= 0.05 else ("above" if test["diff"] > 0 else "below")
            counts[key] += 1
    return Q(counts[sign], None, "d", f"of {sum(counts.values())} run-bins")


@source
def srs_cell(folder: str, config: str, budget: str, metric: str) -> Q:
    """Chapter 3: one configuration's error (cm) at a budget share (`1.0000`, `0.6667`, ...),
    mean ± std over its datasets and model seeds."""
    ms = dig(load(f"{folder}/results.json"), f"configs/{config}/{budget}/{metric}")
    return Q(float(ms["mean"]), float(ms["std"]), ".1f", "cm")  # type: ignore[index]


@source
def count(path: str, keypath: str, value: str) -> Q:
    """How many entries of a list or {key: value} map in a results file equal `value` (e.g.
    the folds that chose one range candidate)."""
    entries = dig(load(path), keypath)
    values = entries.values() if isinstance(entries, dict) else entries
    return Q(sum(str(v) == value for v in values), None, "d")  # type: ignore[union-attr]


@source
def quantile(path: str, keypath: str, q: str, fmt: str = ".1f", unit: str = "") -> Q:
    """A quantile of a list of numbers in a results file."""
    values = sorted(float(v) for v in dig(load(path), keypath))  # type: ignore[union-attr]
    return Q(statistics.quantiles(values, n=1000, method="inclusive")[round(float(q) * 1000) - 1]
             if float(q) < 1 else values[-1], None, fmt, unit)


@source
def caging_cell(folder: str, tail: str, field: str) -> Q:
    """A caging arm: `caged` (% of seeds), `seeds`, or `time` (mean ± std s, caged runs)."""
    arm = dig(load(f"{folder}/results.json"), f"table/{tail}")
    if field == "caged":
        return Q(100 * float(arm["success_rate"]), None, ".0f", "%")  # type: ignore[index]
    if field == "seeds":
        return Q(arm["seeds"], None, "d")  # type: ignore[index]
    time = arm["time_to_cage_s"]  # type: ignore[index]
    return Q(float(time["mean"]), float(time["std"]), ".1f", "s")


# Tables ------------------------------------------------------------------------------------------

def _ms(values: list[float], fmt: str) -> str:
    if not values:
        return ""
    sd = statistics.pstdev(values)
    return f"{statistics.fmean(values):{fmt}} ± {sd:{fmt}}"


@source
def srs(folder: str, metric: str) -> Table:
    """Chapter 3: per configuration, the error (cm) at each budget share of the largest."""
    data = load(f"{folder}/results.json")
    configs = data["configs"]  # type: ignore[index]
    budgets = sorted({b for c in configs.values() for b in c}, key=float)
    rows = [["configuration", *[f"{float(b) * 100:.0f} % of budget" for b in budgets]]]
    for name, by_budget in configs.items():
        rows.append([name, *[_stat(by_budget[b][metric], ".1f") if b in by_budget else ""
                             for b in budgets]])
    return rows


@source
def oc_table42(folder: str) -> Table:
    """Table 4.2: AUC on all unstable samples, mean ± std over the folder's runs."""
    data = load(f"{folder}/results.json")
    rows = [["method", "AUC"]]
    for method, ms in data["table4_2_auc_m2"].items():  # type: ignore[index]
        rows.append([method, f"{ms['mean']:.3f} ± {ms['std']:.3f}"])
    return rows


@source
def oc_fig48(folder: str) -> Table:
    """Fig 4.8: AUC by time bin, mean ± std over the folder's runs."""
    data = load(f"{folder}/results.json")["fig4_8_auc_by_bin_m2"]  # type: ignore[index]
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
    runs = load(f"{folder}/results.json")["runs"]  # type: ignore[index]
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
    a, b = (load(f"{f}/results.json")["runs"] for f in (base, other))  # type: ignore[index]
    shared = [r for r in a if r in b]  # type: ignore[operator]
    methods = [m for m in a[shared[0]] if m in b[shared[0]] and m != "iogen_vs_dsvdd"]
    rows = [["method", *[f"{r}: {base} / {other}" for r in shared], "mean difference"]]
    for m in methods:
        pairs = [(a[r][m]["auc_all"], b[r][m]["auc_all"]) for r in shared]
        rows.append([m, *[f"{x:.3f} / {y:.3f}" for x, y in pairs],
                     f"{sum(y - x for x, y in pairs) / len(pairs):+.3f}"])
    return rows


def _srs_models(folder: str) -> dict[tuple[str, int, int, int], float]:
    """A chapter-3 folder's per-model reports (`models/<config>_b<budget>_d<j>_m<i>.json`):
    the error of all predictions (cm), by (configuration, budget %, dataset, model seed)."""
    out = {}
    for file in sorted((RESULTS / folder / "models").glob("*.json")):
        match = re.fullmatch(r"(.+)_b(\d+)_d(\d+)_m(\d+)", file.stem)
        if match:
            out[(match[1], int(match[2]), int(match[3]), int(match[4]))] = float(
                load(f"{folder}/models/{file.name}")["mean_error_cm"])  # type: ignore[index]
    return out


@source
def srs_pairs(base: str, other: str, spread: str = "") -> Table:
    """Two chapter-3 folders on their common models (same configuration, budget, dataset and
    model seed): per configuration and budget the error of all predictions (cm) of the paired
    models in each, and their mean difference (other - base); then every distinct pair's
    difference beside the model seed-to-seed differences (seeds 1, 2 - seed 0) of `spread`'s
    (default: base's) models of those configurations and budgets."""
    a, b = _srs_models(base), _srs_models(other)
    shared = [key for key in b if key in a]
    cells = sorted({key[:2] for key in shared})
    rows = [["configuration", "budget %", base, other, "mean difference"]]
    for config, budget in cells:
        keys = [k for k in shared if k[:2] == (config, budget)]
        rows.append([config, str(budget), _ms([a[k] for k in keys], ".2f"),
                     _ms([b[k] for k in keys], ".2f"),
                     f"{statistics.fmean(b[k] - a[k] for k in keys):+.2f}"])
    s = _srs_models(spread or base)
    # a model shared by two cells (Rand-Only's data begins SRS's) is one training: once here
    pairs = list(dict.fromkeys((a[k], b[k]) for k in shared))
    seeds = list(dict.fromkeys((v, s[(*k[:3], m)]) for k, v in s.items()
                               if k[3] == 0 and k[:2] in cells for m in (1, 2)
                               if (*k[:3], m) in s))
    for label, diffs in ((f"every distinct pair ({len(pairs)})", [y - x for x, y in pairs]),
                         (f"{spread or base}: seed to seed ({len(seeds)})",
                          [y - x for x, y in seeds])):
        rows.append([label, "", "", "", f"{statistics.fmean(diffs):+.2f} ± "
                     f"{statistics.stdev(diffs):.2f}"])
    return rows


def _share_ci(h: dict) -> str:
    return "" if h["share"] is None else (
        f"{100 * h['share']:.1f} ({100 * h['lo']:.1f} to {100 * h['hi']:.1f})")


@source
def gradcam_hits(folder: str) -> Table:
    """§4.7.4 scored on a simulated colony: per map, the share (%) of true duel/bite boxes its
    top 5 % touches and the share of its top 5 % on a box, all unstable samples with a box,
    with the bootstrap 95 % interval."""
    data = load(f"{folder}/results.json")["gradcam"]["top5"]  # type: ignore[index]
    rows = [["map", "boxes hit (%)", "top-5 % pixels on a box (%)"]]
    for name, kind in data.items():
        rows.append([name, _share_ci(kind["boxes_hit"]["all"]),
                     _share_ci(kind["pixels_on_boxes"]["all"])])
    return rows


@source
def gradcam_bins(folder: str, metric: str) -> Table:
    """One of `gradcam_hits`' measures (%) per day bin, with the samples each bin holds."""
    data = load(f"{folder}/results.json")["gradcam"]["top5"]  # type: ignore[index]
    first = next(iter(data.values()))[metric]["bins"]
    bins = sorted(first, key=lambda b: int(re.findall(r"\d+", b)[0]))
    rows = [["map", *bins]]
    for name, kind in data.items():
        rows.append([name, *[_share_ci(kind[metric]["bins"][b]) for b in bins]])
    rows.append(["samples", *[str(first[b]["samples"]) for b in bins]])
    return rows


@source
def s2r(folder: str) -> Table:
    """Sim-to-real: each arm's real-test Head error (cm) by share of the real pool."""
    data = load(f"{folder}/results.json")
    arms = data["arms"]  # type: ignore[index]
    fractions = sorted({f for arm in arms.values() for f in arm}, key=float)
    rows = [["arm", *[f"{float(f) * 100:.0f} % real" for f in fractions]]]
    for arm, by_fraction in arms.items():
        cells = []
        for f in fractions:
            ms = by_fraction.get(f, {}).get("head_cm")
            cells.append(f"{ms['mean']:.2f} ± {ms['std']:.2f}" if ms else "")
        rows.append([arm, *cells])
    return rows


@source
def s2r_pairs(base: str, other: str) -> Table:
    """Two sim-to-real runs of the same arms, folds and seeds: per arm and share of the real
    pool the Head error (cm) of each, mean ± std over seeds, and the difference (other - base):
    paired over the seeds with its 95 % interval, or of the means where a run kept no seed's
    (older runs)."""
    a, b = (load(f"{f}/results.json")["arms"] for f in (base, other))  # type: ignore[index]
    rows = [["arm", "% real", base, other, "difference"]]
    for arm, by_fraction in a.items():  # type: ignore[union-attr]
        for f in sorted(by_fraction, key=float):
            mine, theirs = by_fraction[f], b.get(arm, {}).get(f)  # type: ignore[union-attr]
            if not theirs:
                continue
            x, y = mine["head_cm"], theirs["head_cm"]
            diff = f"{y['mean'] - x['mean']:+.2f}"
            if "head_cm_by_seed" in mine and "head_cm_by_seed" in theirs:
                seeds = mine["head_cm_by_seed"]
                diff = str(Paired.of({s: theirs["head_cm_by_seed"][s] - v
                                      for s, v in seeds.items()}, [base, other]))
            rows.append([arm, f"{float(f) * 100:.0f}", _stat(x, ".2f"), _stat(y, ".2f"), diff])
    return rows


@source
def s2r_sim(real: str, *folders: str) -> Table:
    """Sim-only runs (`experiment sim2real --arm sim`) on different lab data: each one's
    real-fold Head error, its ratio to `real`'s real-only arm on all of the pool (the same
    folds and seeds), on how many folds it beats the first run, and its difference from the
    first paired over the seeds (95 % interval). A run's minutes of lab data and its
    checkpoints' choice are named where they are not the command's defaults."""
    from macrostate_mj.app.experiments.sim2real import Config

    plain = Config()
    data = load(f"{real}/results.json")
    full = data["arms"]["real"]["1"]["head_cm"]["mean"]  # type: ignore[index]
    rows = [["lab data (--randomize)", "sim only, Head (cm)", "÷ real only (100 %)",
             "folds better than the first", "minus the first (cm)"]]
    runs = [load(f"{folder}/results.json") for folder in folders]
    first = runs[0]["arms"]["sim"]["0"]["head_cm_by_seed"]  # type: ignore[index]
    for i, run in enumerate(runs):
        profile, cell = run["profile"], run["arms"]["sim"]["0"]  # type: ignore[index]
        ms, by_seed = cell["head_cm"], cell["head_cm_by_seed"]
        better = sum(by_seed[s] < first[s] for s in first)
        names = profile["randomize"]
        names = [names] if isinstance(names, str) else names or []   # older runs: one
        how = [f"{profile['sim_minutes']:g} min"] \
            if profile.get("sim_minutes", plain.sim_minutes) != plain.sim_minutes else []
        if profile.get("sim_select", plain.sim_select) != plain.sim_select:
            how.append("checkpoint on the real validation block")
        label = nodes.inline()
        label += nodes.literal(text=" or ".join(Path(p).name for p in names) or "none")
        if how:
            label += nodes.Text(f" ({', '.join(how)})")
        rows.append([label, f"{ms['mean']:.2f} ± {ms['std']:.2f}", f"{ms['mean'] / full:.2f}x",
                     f"{better} / {len(first)}" if i else "",
                     str(Paired.of({s: by_seed[s] - first[s] for s in first},
                                   [folders[0], folders[i]])) if i else ""])
    return rows


FIT_LABELS = {"none": "none: the scenario as written",
              "fold": "fold: fitted in each fold on its training blocks (nested)",
              "train": "train: fitted on the real Train.csv (has seen the test blocks)"}


@source
def s2r_fits(folder: str) -> Table:
    """A sim-to-real run's sim-only models by where the lab's factors came from (`--fit`), on
    the same folds and seeds: Head error (cm), its ratio to the real-only arm on all of the
    pool, and the per-seed difference to the first fit's (mean ± std over seeds)."""
    data = load(f"{folder}/results.json")
    fits = data["sim_by_fit"]  # type: ignore[index]
    first = next(iter(fits.values()))["head_cm_by_seed"]
    rows = [["lab factors (--fit)", "sim only, Head (cm)", "÷ real only (100 %)",
             "− the first, per seed (cm)"]]
    for i, (fit, cell) in enumerate(fits.items()):
        diffs = [cell["head_cm_by_seed"][s] - first[s] for s in first]
        rows.append([FIT_LABELS.get(fit, fit), _stat(cell["head_cm"], ".2f"),
                     f"{cell['sim_over_real']:.2f}x" if "sim_over_real" in cell else "",
                     f"{statistics.fmean(diffs):+.2f} ± {statistics.stdev(diffs):.2f}"
                     if i and len(diffs) > 1 else ""])
    return rows


@source
def s2r_fit_runs(fit: str, *folders: str) -> Table:
    """One `--fit` of several sim-to-real runs on the same folds and seeds (different lab
    models): how many parameters it fitted, its sim-only Head error, its ratio to the run's
    real-only arm, and on how many folds it beats the first run's."""
    rows = [["run", "parameters fitted", "sim only, Head (cm)", "÷ real only (100 %)",
             "folds better than the first"]]
    first: dict = {}
    for i, folder in enumerate(folders):
        data = load(f"{folder}/results.json")
        cell = data.get("sim_by_fit", {}).get(fit) or data["arms"]["sim"]["0"]  # type: ignore
        fitted = next(v["fitted"] for k, v in data["fits"].items()  # type: ignore[index]
                      if k.startswith(fit))
        real = data["arms"]["real"]["1"]["head_cm"]["mean"]  # type: ignore[index]
        by_seed = cell["head_cm_by_seed"]
        first = first or by_seed
        better = sum(by_seed[s] < first[s] for s in first)
        rows.append([nodes.literal(text=folder), str(len(fitted)), _stat(cell["head_cm"], ".2f"),
                     f"{cell['head_cm']['mean'] / real:.2f}x",
                     f"{better} / {len(first)}" if i else ""])
    return rows


@source
def s2r_ranges(folder: str) -> Table:
    """The `--randomize` candidates of a sim-to-real run, chosen per fold on its real
    validation block: each candidate's Head error there and on the test blocks (mean ± std
    over the seeds) and on how many folds it was chosen."""
    data = load(f"{folder}/results.json")
    rows = [["fit", "ranges (--randomize)", "validation block, Head (cm)", "test block, Head (cm)",
             "chosen on"]]
    for fit, ranges in data["ranges"].items():  # type: ignore[index,union-attr]
        chosen = list(ranges["chosen_by_seed"].values())
        for name, cell in ranges["candidates"].items():
            rows.append([fit, nodes.literal(text=Path(name).name),
                         _stat(cell["select_head_cm"], ".2f"), _stat(cell["head_cm"], ".2f"),
                         f"{chosen.count(name)} / {len(chosen)}"])
    return rows


def _tuned(folder: str, tuned: str, setting: str) -> Table:
    """A setting chosen per seed and real share on the real validation block (the `sim2real`
    `Tuned` named `tuned`): each candidate's error there and on the test blocks (mean ± std
    over the seeds) and for how many seeds it was kept."""
    from macrostate_mj.app.experiments import sim2real

    table, cells = next((t.table, t.cells) for t in sim2real.TUNED if t.name == tuned)
    data = load(f"{folder}/results.json")
    rows = [["arm", "real data", setting, "validation block, mean error (cm)",
             "test block, Head (cm)", "kept for"]]
    for arm, shares in data[table].items():  # type: ignore[index,union-attr]
        for share, cell in shares.items():
            kept = [f"{w:g}" for w in cell["chosen_by_seed"].values()]
            for value, w in sorted(cell[cells].items(), key=lambda kv: float(kv[0])):
                rows.append([arm, f"{float(share) * 100:.0f} %", value,
                             _stat(w["best_val_cm"], ".2f"), _stat(w["head_cm"], ".2f"),
                             f"{kept.count(value)} / {len(kept)}"])
    return rows


@source
def s2r_mixes(folder: str) -> Table:
    """The mixing arms' lab shares (`--mix-weight`), chosen per seed and real share on the real
    validation block (see `_tuned`)."""
    return _tuned(folder, "mix_weight", "lab share of the loss")


@source
def s2r_finetunes(folder: str) -> Table:
    """The fine-tuned arms' epochs (`--finetune-epochs`), chosen per seed and real share on the
    real validation block (see `_tuned`)."""
    return _tuned(folder, "finetune_epochs", "fine-tuning epochs")


@source
def s2r_ablations(folder: str) -> Table:
    """Each group of lab parameters switched off (`--ablate`): the sim-only Head error and
    its difference to the lab's own on the same seeds, with the 95 % interval over the run's
    units (`Paired.of`: its folds, corrected; the run's own `minus_lab` is over seeds)."""
    data = load(f"{folder}/results.json")
    lab = data["arms"]["sim"]["0"]["head_cm_by_seed"]  # type: ignore[index]
    rows = [["switched off", "sim only, Head (cm)", "minus the lab's (cm)", "95 % interval"]]
    for group, cell in data["ablations"].items():  # type: ignore[index,union-attr]
        d = Paired.of({s: v - lab[s] for s, v in cell["head_cm_by_seed"].items()}, folder)
        rows.append([nodes.literal(text=group), _stat(cell["head_cm"], ".2f"),
                     f"{d.mean:+.2f}", f"[{d.low:+.2f}, {d.high:+.2f}], {d.units}"])
    return rows


def _excesses(folder: str) -> tuple[float, float, float]:
    """One sim-to-real run's sim only and fine-tuned-on-a-quarter Head errors minus real only
    on all of the pool, each paired over its seeds (`paired`'s mean), and real only's mean
    (cm)."""
    path, real = f"{folder}/results.json", "arms/real/1/head_cm_by_seed"
    return (paired(path, "arms/sim/0/head_cm_by_seed", real).mean,
            paired(path, "arms/finetune/0.25/head_cm_by_seed", real).mean,
            statistics.fmean(dig(load(path), real).values()))  # type: ignore[union-attr]


@source
def s2r_transfer(*folders: str) -> Table:
    """Sim-to-real runs of different lab data: each one's sim-only excess over real only (all
    of the pool) beside its fine-tuned-on-a-quarter excess, both paired over its seeds."""
    rows = [["run", "sim only minus real only (cm)", "sim ÷ real", "fine-tuned on 25 % minus "
             "real only (cm)"]]
    for folder in folders:
        sim, tuned, real = _excesses(folder)
        rows.append([nodes.literal(text=folder), f"{sim:+.2f}", f"{(real + sim) / real:.2f}x",
                     f"{tuned:+.2f}"])
    return rows


@source
def sealed(folder: str) -> Table:
    """`experiment s2r-sealed`: each arm's Head error on the sealed test (mean ± std over its
    seeds) and, against real only, the ratio and the difference with their 95 % intervals
    (instances x seeds)."""
    from macrostate_mj.app.experiments.s2r_sealed import ARMS

    r = load(f"{folder}/results.json")
    rows = [["arm", "Head error (cm)", "÷ real only [95 %]", "minus real only (cm) [95 %]"]]
    for arm in ARMS:                         # in the experiment's order
        h = r["arms"][arm]["head_cm"]  # type: ignore[index]
        vs = r["against_real"].get(arm)  # type: ignore[index]
        compared = ["1", "0"]               # real only against itself
        if vs is not None:
            q, d = vs["ratio"], vs["difference"]
            compared = [f"{q['mean']:.2f} [{q['low']:.2f}, {q['high']:.2f}]",
                        f"{d['mean']:+.2f} [{d['low']:+.2f}, {d['high']:+.2f}]"]
        rows.append([arm, f"{h['mean']:.2f} ± {h['std']:.2f} ({h['n']} seeds)", *compared])
    return rows


@source
def sealed_change(before: str, after: str, arm: str) -> Paired:
    """One arm of two `s2r-sealed` runs on the same sealed test: the later's Head error minus
    the earlier's, with its 95 % interval (`core.stats.two_level_bootstrap`: the instances
    shared, each run's seeds apart)."""
    from macrostate_mj.core.stats import two_level_bootstrap

    a, b = ([list(v) for v in load(f"{f}/results.json")["arms"][arm][  # type: ignore[index]
        "head_cm_by_instance"].values()] for f in (after, before))
    d = two_level_bootstrap(a, b)["difference"]
    units = f"{len(a[0])} test instances, {len(a)} and {len(b)} seeds"
    return Paired(d["mean"], d["low"], d["high"], len(a[0]), units, ".2f", "cm")


@source
def gap_ranked(*files: str) -> Table:
    """Ranked sim-to-real gaps (`stats --compare --rank --json` files, one per lab): per
    statistic the worst robot's KS distance in each, in the first file's order."""
    runs = [[json.loads(line) for line in (RESULTS / f).read_text().splitlines()]
            for f in files]
    effects = "effects" in runs[0][0]     # `--effects`: the first file's, beside each row
    stems = [Path(f).stem for f in files]
    named = stems if len(set(stems)) == len(stems) else [f.removesuffix(".jsonl") for f in files]
    rows = [["statistic", *named, "shaped in the lab by",
             *(["Head error without it (cm)"] if effects else [])]]
    for r in runs[0]:
        cells = []
        for run in runs:
            other = next(x for x in run if x["statistic"] == r["statistic"])
            cells.append(f"{other['ks'][other['worst']]:.2f} ({other['worst']})")
        shown = [f"{g} {d['mean']:+.2f} [{d['low']:+.2f}, {d['high']:+.2f}]"
                 for g, d in r.get("effects", {}).items()]
        rows.append([r["statistic"], *cells, ", ".join(r["shaped_by"]),
                     *(["; ".join(shown)] if effects else [])])
    rows.append(["summed", *(f"{sum(x['sum'] for x in run):.2f}" for run in runs), "",
                 *([""] if effects else [])])
    return rows


@source
def retlo_sim(pattern: str) -> Table:
    """Fig 2.2: per case, the chained MLPs' mean and max error (cm) and the 2X heuristic's,
    mean ± std over the run folders `pattern` matches (one a training seed)."""
    runs = [load(str(f.relative_to(RESULTS)))["cases"]  # type: ignore[index]
            for f in sorted(RESULTS.glob(f"{pattern}/results.json"))]
    if not runs:
        raise ValueError(f"no results/{pattern}/results.json")
    robots = sorted({r for c in runs[0].values() for r in c["per_robot"]}, key=_robot_order)
    rows = [["case", "all, mean", "all, max", *[f"{r}, mean" for r in robots], "2X, all mean"]]

    def cell(get: Callable[[dict], float]) -> str:
        return _ms([100 * get(run) for run in runs], ".1f")

    for key, case in runs[0].items():
        rows.append([f"{key}: {case['title']}",
                     cell(lambda r, k=key: r[k]["all"]["mean_error"]),
                     cell(lambda r, k=key: r[k]["all"]["max_error"]),
                     *[cell(lambda r, k=key, b=b: r[k]["per_robot"][b]["mean_error"])
                       if b in case["per_robot"] else "" for b in robots],
                     cell(lambda r, k=key: r[k]["heuristic2x"]["all"]["mean_error"])])
    return rows


def _robot_order(name: str) -> tuple[int, int]:
    return (1, 0) if name == "H" else (0, int(name[1:]))


@source
def caging(folder: str) -> Table:
    """Every Tail of a caging run: caged seeds, time to cage, spacing CV, the Head estimate."""
    table = load(f"{folder}/results.json")["table"]  # type: ignore[index]
    rows = [["Tail", "caged", "time to cage (s)", "final spacing CV", "Head estimate (cm)"]]
    for tail, arm in table.items():
        caged = round(arm["success_rate"] * arm["seeds"])
        rows.append([tail, f"{caged} / {arm['seeds']}", _stat(arm["time_to_cage_s"], ".1f"),
                     _stat(arm["spacing_cv"], ".3f"),
                     _stat(arm.get("head_estimate_error_m", {}), ".1f", 100)])
    return rows


def _stat(ms: dict, fmt: str, scale: float = 1.0) -> str:
    if not ms or ms.get("mean") is None:
        return ""
    return f"{ms['mean'] * scale:{fmt}} ± {ms['std'] * scale:{fmt}}"


@source
def retlo_models(folder: str) -> Table:
    """Fig 2.7: each model's mean error (cm) per test set and robot, mean ± std over seeds."""
    data = load(f"{folder}/results.json")
    rows = [["test set", "robots", "model", "mean error (cm)", "per robot (cm)"]]
    for test in data["tests"]:  # type: ignore[index]
        for model, agg in data["results"][test["name"]].items():  # type: ignore[index]
            per = "; ".join(f"{r} {_stat(v, '.1f')}" if isinstance(v, dict) else f"{r} {v:.1f}"
                            for r, v in agg["per_robot_cm"].items())
            rows.append([test["name"], str(test["n_robots"]), model,
                         _stat(agg["mean_error_cm"], ".1f") if isinstance(agg["mean_error_cm"],
                                                                          dict)
                         else f"{agg['mean_error_cm']:.1f}", per])
    return rows


@source
def retlo_trainings(*folders: str) -> Table:
    """`experiment retlo` runs that differ in how they train for longer chains: per run its
    training (from the manifest), then each learned model's mean error (cm) on every test,
    mean ± std over seeds; the per-fold figures of the cross-validated test in the last
    column, and on how many folds each run beats the first."""
    from estimators.retlo import MODEL_KINDS
    from macrostate_mj.app.experiments.retlo import CV_TEST

    runs = [(load(f"{f}/results.json"), load(f"{f}/manifest.json")["config"])  # type: ignore
            for f in folders]
    tests = [t["name"] for t in runs[0][0]["tests"]]  # type: ignore[index]
    rows = [["training", "model", *tests, "per fold (cross-validated)",
             "folds better than the first"]]
    for i, (data, config) in enumerate(runs):
        label = "split" if config.get("split") else \
            "chained" if config.get("chained", True) else "not chained"
        if config.get("precision", "fp32") != "fp32":
            label += f", {config['precision']}"
        for model in MODEL_KINDS:
            cells = [_stat(data["results"][t][model]["mean_error_cm"], ".2f") for t in tests]
            per = data["results"].get(CV_TEST, {}).get(model, {}).get("per_seed_cm", [])
            first = runs[0][0]["results"].get(CV_TEST, {}).get(model, {}).get("per_seed_cm", [])
            better = sum(a < b for a, b in zip(per, first, strict=True))
            rows.append([nodes.literal(text=label), model, *cells,
                         " ".join(f"{v:.2f}" for v in per),
                         f"{better} / {len(per)}" if i and per else ""])
    return rows


@source
def retlo_calibration(folder: str) -> Table:
    """Gaussian ReTLo models of `experiment retlo --uncertainty gaussian`: per test set, model
    and robot (and pooled), the share of true positions inside the 50 % and 90 % regions and
    the NLL, mean ± std over seeds; where the models carry fitted region radii, the coverage
    of the plain Gaussian's χ² regions beside."""
    data = load(f"{folder}/results.json")
    head = ["test set", "model", "robot", "coverage 50 %", "coverage 90 %"]
    rows: Table = []
    for test in data["tests"]:  # type: ignore[index]
        for model, agg in data["results"][test["name"]].items():  # type: ignore[index]
            for who, cal in agg.get("calibration", {}).items():
                plain = [_stat(cal[k], ".2f") for k in ("gaussian_coverage_50",
                                                        "gaussian_coverage_90") if k in cal]
                rows.append([test["name"], model, who, _stat(cal["coverage_50"], ".2f"),
                             _stat(cal["coverage_90"], ".2f"), *plain, _stat(cal["nll"], ".2f")])
    fitted = bool(rows) and len(rows[0]) > 6
    return [head + (["Gaussian χ² 50 %", "Gaussian χ² 90 %"] if fitted else []) + ["NLL"],
            *rows]


REFIT_KEYS = ("coverage_50", "coverage_90", "gaussian_coverage_50", "gaussian_coverage_90")


def _arm(folder: str, arm: str) -> list[dict]:
    """The `evaluate retlo` reports of one arm of a `calibrate retlo` comparison, a seed each
    (`reports/<arm>_s<seed>.json`)."""
    found = sorted((RESULTS / folder / "reports").glob(f"{arm}_s*.json"))
    if not found:
        raise ValueError(f"results/{folder}/reports holds no {arm}_s*.json")
    return [json.loads(p.read_text()) for p in found]


@source
def refit(folder: str, arm: str, keypath: str, fmt: str = ".2f") -> Q:
    """One figure of a `calibrate retlo` arm's reports, mean ± std over its seeds."""
    ms = mean_std([float(dig(r, keypath)) for r in _arm(folder, arm)])  # type: ignore[arg-type]
    return Q(ms["mean"], ms["std"], fmt, "")


@source
def retlo_refit(folder: str) -> Table:
    """`calibrate retlo` (results/retlo_lab5_calibrated): per arm and robot, the coverage of the
    model's regions and of the plain Gaussian's χ² regions, mean ± std over model seeds (each
    seed's `evaluate retlo` report on the test chains)."""
    rows = [["regions fitted on", "robot", "coverage 50 %", "coverage 90 %", "Gaussian χ² 50 %",
             "Gaussian χ² 90 %"]]
    label = {"trained": "lab 3-robot validation (training)",
             "refitted": "lab 5-robot chains, seed 3 (calibrate retlo)"}
    for arm in label:
        reports = _arm(folder, arm)
        for who in (w for w in reports[0]["calibration"] if w != "nll_unit"):
            rows.append([label[arm], who, *(_stat(mean_std(
                [r["calibration"][who][k] for r in reports]), ".2f") for k in REFIT_KEYS)])
    return rows


@source
def retlo_fig29(folder: str) -> Table:
    """Fig 2.9: the inside-of-curve bias (cm) and the largest-error share per robot and model."""
    data = load(f"{folder}/results.json")["fig2_9"]  # type: ignore[index]
    rows = [["model", "robot", "toward the inside (cm)", "curved steps",
             "instants it errs most (%)"]]
    for model in ("fc", "lstm"):
        part = data[model]
        for robot, inside in part["inside_cm"].items():
            share = part["largest_error_share"].get(robot)
            rows.append([model, robot, _stat(inside, ".2f"), str(part["curved_steps"][robot]),
                         _stat(share, ".0f", 100) if share else ""])
    return rows


@source
def ch3_gap(folder: str) -> Table:
    """`experiment ch3-gap`: each model's 5-robot error, its validation error, and its Head
    error per 3-robot module given true inputs (cm; one dataset and one model each)."""
    data = load(f"{folder}/results.json")
    first = next(iter(data["scenarios"]))  # type: ignore[index]
    rows: Table = []
    for part, label in (("scenarios", "scenario"), ("variants", f"training on {first}")):
        for name, r in data[part].items():  # type: ignore[index]
            if part == "variants" and name == "ours":
                continue                    # the first scenario's row already
            rows.append([label, name, f"{r['all_cm']:.1f}", f"{r['best_val_cm']:.1f}",
                         *(f"{v:.1f}" for v in r["modules_cm"].values())])
    modules = list(data["scenarios"][first]["modules_cm"])  # type: ignore[index]
    return [["", "", "5-robot error", "validation", *modules], *rows]


@source
def uncertainty(folder: str, split: str) -> Table:
    """Point against Gaussian ReTLo (and their ensemble): mean error (cm) and calibration."""
    data = load(f"{folder}/results.json")[split]  # type: ignore[index]
    cal = data["gaussian_calibration"]
    rows = [["model", "mean error (cm)", "coverage_50", "coverage_90", "NLL"]]
    rows.append(["point", _ms(data["point_cm"], ".2f"), "", "", ""])
    rows.append(["Gaussian", _ms(data["gaussian_cm"], ".2f"),
                 _ms([c["coverage_50"] for c in cal], ".2f"),
                 _ms([c["coverage_90"] for c in cal], ".2f"), _ms([c["nll"] for c in cal], ".2f")])
    ens = data["ensemble_calibration"]
    rows.append(["ensemble of the Gaussians", f"{data['ensemble_cm']:.2f}",
                 f"{ens['coverage_50']:.2f}", f"{ens['coverage_90']:.2f}", f"{ens['nll']:.2f}"])
    return rows


@source
def learned_tail(folder: str) -> Table:
    """Each Tail's frozen-estimator error (cm) on held-out seeds, its paired test against the
    Passive Tail, the chain's spacing and its breaks."""
    table = load(f"{folder}/results.json")["table"]  # type: ignore[index]
    rows = [["Tail", "Head error (cm)", "all robots (cm)", "p vs passive", "better seeds",
             "spacing (cm)", "breaks"]]
    for tail, arm in table.items():
        test = arm.get("vs_passive") or {}
        if test.get("wilcoxon_p") is None:      # the Passive Tail against itself
            test = {}
        rows.append([tail, _stat(arm["head_error_m"], ".1f", 100),
                     _stat(arm["all_error_m"], ".1f", 100),
                     f"{test['wilcoxon_p']:.2g}" if test else "",
                     f"{test['better']} / {test['pairs']}" if test else "",
                     f"{arm['spacing_m']['mean'] * 100:.1f}", f"{arm['breaks']} / {arm['seeds']}"])
    return rows


@source
def learned_tail_seeds(*folders: str) -> Table:
    """The learned Tail of each PPO training seed (one `experiment learned-tail --seed` run
    per folder) on the same held-out seeds: its Head error, the paired test against Passive,
    its breaks."""
    rows = [["PPO seed", "Head error (cm)", "Passive (cm)", "p vs passive", "better seeds",
             "breaks"]]
    for folder in folders:
        data = load(f"{folder}/results.json")
        table = data["table"]  # type: ignore[index]
        learned, test = table["learned"], table["learned"]["vs_passive"]
        rows.append([str(data["config"]["seed"]), _stat(learned["head_error_m"], ".1f", 100),  # type: ignore[index]
                     _stat(table["passive"]["head_error_m"], ".1f", 100),
                     f"{test['wilcoxon_p']:.2g}", f"{test['better']} / {test['pairs']}",
                     f"{learned['breaks']} / {learned['seeds']}"])
    return rows


SYSID_FEATURES = {"spacing_cm": "spacing (cm)", "speed_cm_s": "speed (cm/s)",
                  "wait_share": "time waiting", "jitter_cm": "jitter (cm)",
                  "turn_deg_s": "turn rate (°/s)", "accel_cm_s2": "acceleration (cm/s²)",
                  "heading_change_deg": "heading change (°)",
                  "speed_acf": "speed autocorr. (lag 1; KS over lags 1-10)",
                  "turn_acf": "turn autocorr. (lag 1; KS over lags 1-10)"}


SIGNED = {"turn_deg_s", "heading_change_deg", "accel_cm_s2"}   # medians near 0 say nothing


def _ks_rows(rows: list[dict]) -> dict[tuple[str, str], tuple[float, float, float]]:
    """(feature, robot) -> (KS, sim median, real median), each autocorrelation's lags as the
    fit scores them (KS averaged over lags, medians of lag 1); pooled rows left out."""
    out: dict[tuple[str, str], list] = {}
    for r in rows:
        if r["robot"] == "pooled":
            continue
        family = r["feature"].split("_lag")[0]
        cell = out.setdefault((family, r["robot"]), [[], None, None])
        cell[0].append(r["ks"])
        if "_lag" not in r["feature"] or r["feature"].endswith("_lag1"):
            cell[1], cell[2] = r["median"]
    return {k: (statistics.fmean(v[0]), v[1], v[2]) for k, v in out.items()}


def _chain_order(name: str) -> int:
    """H, F1, F2, ..., T; a pair (`H-F1`) by its first robot."""
    first = name.split("-")[0]
    return 0 if first == "H" else 99 if first == "T" else int(first[1:])


@source
def sysid_ks(folder: str) -> Table:
    """A `sysid` fit's before/after table: per feature and robot the medians (real Val, the
    scenario before, the fit) and the KS distance to the real Train and Val files, before ->
    after; the summed score last."""
    fit = load(f"{folder}/fit.json")
    tables = {(when, split): _ks_rows(fit["rows"][when][split])  # type: ignore[index]
              for when in ("before", "after") for split in ("train", "val")}
    rows = [["feature", "robot", "real Val", "before", "after", "KS Train", "KS Val"]]
    keys = sorted(tables["before", "val"], key=lambda k: (list(SYSID_FEATURES).index(k[0]),
                                                          _chain_order(k[1])))
    for family, robot in keys:
        _, before, real = tables["before", "val"][family, robot]
        after = tables["after", "val"][family, robot][1]
        ks = [f"{tables['before', s][family, robot][0]:.2f} → "
              f"{tables['after', s][family, robot][0]:.2f}" for s in ("train", "val")]
        medians = ["", "", ""] if family in SIGNED else \
            [f"{real:.2f}", f"{before:.2f}", f"{after:.2f}"]
        rows.append([SYSID_FEATURES[family], robot, *medians, *ks])
    rows.append(["summed KS", "", "", "", "",
                 *[f"{fit[s]['before']:.2f} → {fit[s]['after']:.2f}"  # type: ignore[index]
                   for s in ("train", "val")]])
    return rows


@source
def sysid_fits(*folders: str) -> Table:
    """`sysid` fits of one lab under different rules: what each one's scenario file
    (`scenario.toml` beside its fit; none: the lab itself) changes, the summed KS on Train and
    Val before -> after, and the fitted rear-robot factors."""
    rows = [["rule (the scenario's change)", "summed KS Train", "summed KS Val", "k_f ×",
             "k_t ×", "chain cap ×"]]
    for folder in folders:
        fit = load(f"{folder}/fit.json")
        file = RESULTS / folder / "scenario.toml"
        table = tomllib.loads(file.read_text()) if file.is_file() else {}
        changes = [f"{section}.{key} = {json.dumps(value)}" for section, keys in table.items()
                   if isinstance(keys, dict) for key, value in keys.items() if key != "kind"]
        label = nodes.literal(text=", ".join(changes)) if changes else "none (the lab)"
        ks = [f"{fit[s]['before']:.2f} → {fit[s]['after']:.2f}"  # type: ignore[index]
              for s in ("train", "val")]
        fitted = fit["fitted"]  # type: ignore[index]
        rows.append([label, *ks, *(f"{fitted[k]:.2f}" for k in ("k_f", "k_t", "chain_speed"))])
    return rows


@source
def all_index(folder: str) -> Table:
    """An `experiment all` folder's index: per experiment its status, wall time and stage
    timings (from its manifest)."""
    index = load(f"{folder}/index.json")
    rows = [["experiment", "profile", "status", "wall (min)", "stages (min)"]]
    for name, entry in index["experiments"].items():  # type: ignore[index]
        file = RESULTS / folder / name / "manifest.json"
        stages = json.loads(file.read_text()).get("timings_s", {}) if file.is_file() else {}
        rows.append([name, index["profile"], entry["status"],  # type: ignore[index]
                     f"{entry['wall_s'] / 60:.1f}",
                     ", ".join(f"{k} {v / 60:.1f}" for k, v in stages.items() if k != "total")])
    return rows


@source
def soak(*folders: str) -> Table:
    """Soaks' summaries, one column each: runs, simulated time and every fault count."""
    summaries = [load(f"{folder}/soak.json")["summary"] for folder in folders]  # type: ignore[index]
    keys = ["scenario", "robots", "runs", "seconds", "tips", "nans", "escapes", "climbs",
            "intrusions", "warnings", "max_tilt_deg", "max_lift_mm"]
    rows = [["figure", *(["value"] if len(folders) == 1 else [Path(f).name for f in folders])]]
    for key in (k for k in keys if k in summaries[0]):
        rows.append([key, *(_soak_cell(summary[key]) for summary in summaries)])
    return rows


def _soak_cell(value: object) -> str:
    if isinstance(value, float):
        return f"{value:.2f}" if not value.is_integer() else str(int(value))
    return str(value)


@source
def track_soak(folder: str) -> Table:
    """Tracked soaks, one sub-folder a lab (`soak --track --out`): its summary row each."""
    rows = [["folder", "markers", "robots", "runs x s", "unhealthy", "min detected (rows)",
             "max hidden", "max median mm", "max p99 mm", "max heading p99 deg", "max flipped",
             "max identity", "s/run"]]
    for soak_file in sorted((RESULTS / folder).glob("*/soak.json")):
        summary = json.loads(soak_file.read_text())["summary"]
        manifest = json.loads((soak_file.parent / "manifest.json").read_text())
        scenario = manifest["config"]["tasks"]["scenario"]
        kind = scenario.get("markers", {}).get("dictionary") and "aruco" or "colour"
        rows.append([soak_file.parent.name, kind, str(summary["robots"]),
                     f"{summary['runs']} x {summary['seconds']:g}", str(summary["unhealthy"]),
                     f"{summary['min_detected']:.4f}", f"{summary['max_hidden']:.4f}",
                     f"{summary['max_median_mm']:.2f}", f"{summary['max_p99_mm']:.2f}",
                     f"{summary['max_heading_p99_deg']:.1f}",
                     f"{summary['max_heading_flips']:.4f}", f"{summary['max_identity']:.4f}",
                     f"{summary['wall_s_per_run']:.1f}"])
    return rows


@source
def bench(path: str) -> Table:
    """`bench --json` lines: suite, figure, value, limit and ratio."""
    rows = [["suite", "figure", "value", "limit", "ratio", "config"]]
    for line in load(path):  # type: ignore[union-attr]
        config = line.get("config")
        config = json.dumps(config) if isinstance(config, dict) else (config or "")
        rows.append([line["suite"], line["name"], _num(line["value"]) + f" {line['unit']}",
                     _num(line.get("limit")), _num(line.get("ratio")), config])
    return rows


def _num(value: object) -> str:
    if value is None:
        return ""
    value = float(value)  # type: ignore[arg-type]
    if math.isfinite(value) and value.is_integer():
        return str(int(value))
    return f"{value:.3g}" if abs(value) < 100 else f"{value:.0f}"


# Docutils glue -------------------------------------------------------------------------------

def _record(env: object, expression: str, shown: object) -> None:
    """Note what a page was given by which source, for the docs test to bind each number."""
    if isinstance(shown, list):
        shown = [[c.astext() if isinstance(c, nodes.Node) else str(c) for c in row]
                 for row in shown]
    measured = env.__dict__.setdefault("measured_numbers", {})
    measured.setdefault(env.docname, []).append([expression, shown])  # type: ignore[attr-defined]


def _purge(app: object, env: object, docname: str) -> None:
    env.__dict__.get("measured_numbers", {}).pop(docname, None)


def _merge(app: object, env: object, docnames: set[str], other: object) -> None:
    mine = env.__dict__.setdefault("measured_numbers", {})
    for name, rows in other.__dict__.get("measured_numbers", {}).items():
        if name in docnames:
            mine[name] = rows


def _stale(app: object, env: object, added: set, changed: set, removed: set) -> list[str]:
    """Every page that shows numbers is read again each build: its results may have changed
    while its text did not."""
    return sorted(env.__dict__.get("measured_numbers", {}))


def _dump(app: object, error: Exception | None) -> None:
    """`_numbers.json` in the output folder: per page, each source and what it showed."""
    if error is None:
        measured = app.env.__dict__.get("measured_numbers", {})  # type: ignore[attr-defined]
        (Path(app.outdir) / NUMBERS).write_text(json.dumps(measured, indent=1))  # type: ignore[attr-defined]


def table_node(rows: Table) -> nodes.table:
    """A plain docutils table: first row the header."""
    table = nodes.table(classes=["results-table", "colwidths-auto"])   # HTML: widths by content
    group = nodes.tgroup(cols=len(rows[0]))
    table += group
    # Widths matter to the text builder (the docs test reads its output): a column as wide as
    # its longest cell, up to 40 characters, so no number is broken across lines.
    for j in range(len(rows[0])):
        width = max(len(c.astext() if isinstance(c, nodes.Node) else str(c)) for c in
                    (row[j] for row in rows))
        group += nodes.colspec(colwidth=min(max(width, 3), 40))
    for part, chunk in ((nodes.thead(), rows[:1]), (nodes.tbody(), rows[1:])):
        for cells in chunk:
            row = nodes.row()
            for cell in cells:
                entry = nodes.entry()
                if isinstance(cell, nodes.Node):
                    para = nodes.paragraph()
                    para += cell
                    entry += para
                else:
                    entry += nodes.paragraph(text=str(cell))
                row += entry
            part += row
        group += part
    return table


class NumberRole(SphinxRole):
    """``{n}`source(args)` ``: one quantity, printed as its source formats it."""

    def run(self) -> tuple[list[nodes.Node], list[nodes.system_message]]:
        try:
            text = str(call(self.text))
        except (ValueError, KeyError, IndexError, TypeError) as exc:
            msg = self.inliner.reporter.error(f"{self.text}: {exc}", line=self.lineno)
            return [nodes.problematic(self.rawtext, self.rawtext)], [msg]
        _record(self.env, self.text, text)
        return [nodes.inline(self.rawtext, text, classes=["measured"])], []


class ResultsTable(Directive):
    """``{results-table} source(args)``: a table computed from results files."""

    required_arguments = 1
    final_argument_whitespace = True

    def run(self) -> list[nodes.Node]:
        try:
            rows = call(self.arguments[0])
        except (ValueError, KeyError, IndexError, TypeError) as exc:
            raise self.error(f"{self.arguments[0]}: {exc}") from exc
        _record(self.state.document.settings.env, self.arguments[0], rows)
        return [table_node(rows)]  # type: ignore[arg-type]


class Claims(Directive):
    """``{claims} chapter``: the chapter's claims judged by `macrostate_mj.app.claims` (the
    code `macrostate-mj claims` runs): the text's value against ours with its interval and n,
    what it was compared with, and the verdict by the one rule of the reproduction index."""

    required_arguments = 1

    def run(self) -> list[nodes.Node]:
        from macrostate_mj.app.claims import judge_all
        from macrostate_mj.core.errors import UserError

        try:
            judged = judge_all(RESULTS, [self.arguments[0]])
        except UserError as exc:
            raise self.error(str(exc)) from exc
        folders = sorted({j.folder for j in judged if j.folder})
        shared = len(folders) == 1
        header = ["figure", "claim", "dissertation", "ours [95 % interval], n", "compared with",
                  "verdict", "finding"]
        rows: list[list] = [header if shared else [*header[:6], "results", header[6]]]
        for j in judged:
            decide = f"; {j.would_decide} units would decide it" if j.would_decide else ""
            row = [j.figure, j.claim, j.text, j.ours_text + (" (smoke)" if j.smoke else ""),
                   j.comparator, f"{j.verdict}: {j.why}{decide}", j.finding]
            if not shared:
                row.insert(6, j.folder or "")
            rows.append(row)
        _record(self.state.document.settings.env, f"claims {self.arguments[0]}", rows)
        out: list[nodes.Node] = [table_node(rows)]
        if shared:
            para = nodes.paragraph(text="Results: ")
            para += nodes.literal(text=f"results/{folders[0]}")
            out.append(para)
        return out


class ClaimsSummary(Directive):
    """``{claims-summary}``: the rule, stated once, each judged folder's units, nesting,
    correction and what its units share (as results/index.toml declares them), and each
    chapter's count of verdicts."""

    def run(self) -> list[nodes.Node]:
        from macrostate_mj.app.claims import (
            RULE,
            VERDICTS,
            counts,
            design_of,
            judge_all,
            load_claims,
        )
        from macrostate_mj.app.provenance import RESULT_RULE

        judged = judge_all(RESULTS)
        chapters = list(dict.fromkeys(j.chapter for j in judged))
        rows: list[list] = [["chapter", *VERDICTS, "claims"]]
        for chapter in [*chapters, "all"]:
            mine = [j for j in judged if chapter in ("all", j.chapter)]
            rows.append([chapter, *counts(mine).values(), len(mine)])
        _record(self.state.document.settings.env, "claims-summary", rows)
        units: list[list] = [["results", "unit", "nested in it (averaged)", "correction",
                              "every unit shares"]]
        seen: set[tuple] = set()
        for chapter in load_claims().values():
            for claim in chapter:
                d = design_of(claim, index())
                key = (claim["folder"], d)
                if key in seen:
                    continue
                seen.add(key)
                units.append([nodes.literal(text=claim["folder"]),
                              d.unit + (" (one training)" if d.trainings == 1 else ""),
                              d.within or "-", d.correction(), d.shared or "-"])
        _record(self.state.document.settings.env, "claims-units", units)
        return [nodes.paragraph(text=RULE), table_node(units),
                nodes.paragraph(text=RESULT_RULE), table_node(rows)]


class ClaimsChanges(Directive):
    """``{claims-changes} file``: the verdicts before the units, corrections and margins of
    the rule (`claims --json` as it printed them, kept in `file` beside the page) against
    today's, counted per chapter, and every claim whose verdict changed with today's reason."""

    required_arguments = 1

    def run(self) -> list[nodes.Node]:
        from macrostate_mj.app.claims import VERDICTS, counts, judge_all

        here = Path(self.state.document.current_source).parent
        before = [json.loads(line) for line in (here / self.arguments[0]).read_text()
                  .splitlines() if line.strip()]
        after = judge_all(RESULTS)
        was = {(b["chapter"], b["figure"], b["claim"]): b for b in before}
        rows: list[list] = [["chapter", *[f"{v} (before → after)" for v in VERDICTS]]]
        for chapter in dict.fromkeys(j.chapter for j in after):
            old = [b for b in before if b["chapter"] == chapter]
            new = counts([j for j in after if j.chapter == chapter])
            rows.append([chapter, *[f"{sum(b['verdict'] == v for b in old)} → {new[v]}"
                                    for v in VERDICTS]])
        changed: list[list] = [["chapter", "figure", "claim", "before", "after", "why"]]
        for j in after:
            b = was.get((j.chapter, j.figure, j.claim))
            if b is None:
                raise self.error(f"{j.figure} ({j.claim}) is not in {self.arguments[0]}")
            if b["verdict"] != j.verdict:
                changed.append([j.chapter, j.figure, j.claim,
                                f"{b['verdict']}, n {b['n']}", f"{j.verdict}, n {j.n} ({j.unit})",
                                j.why])
        env = self.state.document.settings.env
        _record(env, "claims-changes counts", rows)
        _record(env, "claims-changes", changed)
        return [table_node(rows), table_node(changed)]


def _units(entry: dict) -> str:
    """How many units a folder's figures rest on, and which (as `results/index.toml` declares
    them): independent ones, or folds and splits whose training data overlap."""
    unit = entry.get("unit")
    if not unit:
        return f"{entry['units']} independent units"
    what = f"{entry['units']} {unit}s"
    if entry.get("folds") or entry.get("split_ratio"):
        return what + " (their training data overlap: intervals Nadeau-Bengio corrected)"
    return what + " (independent)"


class Provenance(Directive):
    """``{provenance} folder``: where a results folder comes from and what kind of figure it is."""

    required_arguments = 1

    def run(self) -> list[nodes.Node]:
        folder = self.arguments[0]
        entry = index().get(folder)
        if entry is None:
            raise self.error(f"results/{folder} is not in results/index.toml")
        from macrostate_mj.app.provenance import disclosures, is_result

        if entry["kind"].startswith("result") != is_result(entry):
            raise self.error(f"results/index.toml [{folder}]: its kind contradicts the rule")
        parts = [f"results/{folder}", entry["kind"], _units(entry), *disclosures(entry)]
        manifest = RESULTS / folder / "manifest.json"
        if manifest.is_file():
            data = json.loads(manifest.read_text())
            when = datetime.fromtimestamp(data["created_unix"], UTC).strftime("%Y-%m-%d")
            parts.append(when)
            machine = data.get("machine")
            if isinstance(machine, dict):
                parts.append(str(machine.get("cpu") or machine.get("processor") or ""))
            made = data.get("code")
            if made is None:        # made before manifests kept it: say so, never guess
                parts.append("code not recorded (an earlier manifest)")
            elif made.get("commit"):
                parts.append(f"code {made['commit'][:7]}" + (" with changes" if made["dirty"]
                                                            else ""))
        para = nodes.paragraph(classes=["provenance"])
        _record(self.state.document.settings.env, f"provenance {folder}",
                [[*parts, entry["command"]]])
        para += nodes.emphasis(text=" · ".join(p for p in parts if p) + ". ")
        para += nodes.literal(text=entry["command"])
        return [para]


def setup(app: object) -> dict:
    app.add_role("n", NumberRole())  # type: ignore[attr-defined]
    app.add_directive("results-table", ResultsTable)  # type: ignore[attr-defined]
    app.add_directive("claims", Claims)  # type: ignore[attr-defined]
    app.add_directive("claims-summary", ClaimsSummary)  # type: ignore[attr-defined]
    app.add_directive("claims-changes", ClaimsChanges)  # type: ignore[attr-defined]
    app.connect("env-purge-doc", _purge)  # type: ignore[attr-defined]
    app.connect("env-merge-info", _merge)  # type: ignore[attr-defined]
    app.connect("build-finished", _dump)  # type: ignore[attr-defined]
    app.connect("env-get-outdated", _stale)  # type: ignore[attr-defined]
    app.add_directive("provenance", Provenance)  # type: ignore[attr-defined]
    return {"parallel_read_safe": True, "version": "1"}
