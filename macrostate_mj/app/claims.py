"""The dissertation's claims judged on the committed results by one rule (`RULE`).

`claims.toml` beside this module gives per claim the text's value or order, where ours lives in
a results folder (a *source* expression such as ``srs(srs_text, passive, 1.0000)``) and its kind.
Every source returns a `Figure`: ours per run, with per-run values where the records keep them
so that orderings pair them. What is independent is declared beside the results, not guessed from
the run count: each folder's entry of `results/index.toml` (a claim may override it) names its
unit and how units nest (`Design`), and `judge` averages nested runs to that unit and corrects
overlapping folds before any interval is drawn. The `claims` command and the docs' chapter pages
both call `judge_all`, so they cannot differ.
"""

from __future__ import annotations

import json
import re
import tomllib
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from functools import cache
from importlib import import_module
from pathlib import Path

from macrostate_mj.core import stats
from macrostate_mj.core.errors import UserError

CLAIMS = Path(__file__).with_name("claims.toml")
ALPHA = 0.05
# a value claim's margin on its metric's own scale: (absolute, share of the text's value); 10 %
# of an AUC would be 0.05-0.08, wider than the gaps the text ranks
MARGINS: dict[str, tuple[float, float]] = {"auc": (0.02, 0.0), "cm": (0.0, 0.1),
                                           "%": (0.0, 0.1)}
# the same seed and command on two CPUs (one with AVX-512, bf16 and fp16 instructions): what
# makes one training's figure move although each machine repeats it bit for bit
MACHINES = ("IO-GEN's AUC on one real held-out split .757 and .694, the chained LSTM's 3-robot "
            "error with seed 0 4.6 and 6.5 cm")
RULE = ("Units: each row's interval is over the independent units its folder declares in "
        "results/index.toml (a seed with its own data and test, a cross-validated fold, a "
        "dataset, a split, or the test instances of one training), shown beside its number; "
        "runs nested in a unit (the seeds of one split) are averaged to it first, never counted "
        "apart, and what every unit shares (one fixed test file, one dev set) is named beside "
        "the number: the interval holds none of its sampling. Corrections: folds that overlap "
        "in their training data get Nadeau and Bengio's corrected resampled t (the variance of "
        "the mean s² (1/k + n_test/n_train) instead of s²/k; n_test/n_train = 1/(k - 1) for k "
        "contiguous folds; random train/test splits of one pool whose training sets overlap "
        "alike, with their n_test/n_train); every other interval is Student's t over the "
        "units. Margins, on "
        "the metric's own scale: an AUC ± 0.02, an error in cm ± 10 % of the text's value, a "
        "percentage ± 10 % of the text's value, or the row's stated reason. A value claim "
        "agrees when our 95 % interval lies inside the text's value ± its margin, disagrees "
        "when it lies wholly outside it, and is inconclusive otherwise. An ordering agrees when "
        "a one-sided t test over the same units (paired where the records pair them, else "
        "Welch) rejects the reverse order at p < .05, and disagrees when it rejects the text's "
        "order; a claim over several comparisons (\"every step\", \"each model\") agrees only "
        "when every one agrees and disagrees when any one rejects the text's order at .05 "
        "divided by their count. A figure of one training (one seed) says so and is "
        "inconclusive: the same seed moves between machines (" + MACHINES + "), more than the "
        "margins. Anything inconclusive gives the number of units that would decide it at the "
        "observed spread. A row measured elsewhere than where the text speaks is not "
        "comparable, and a row whose text gives neither a number nor an order is qualitative: "
        "neither is counted as agree.")
VERDICTS = ("agree", "disagree", "inconclusive", "not comparable", "qualitative")


class ClaimsError(UserError):
    """A claims file or results folder that cannot be judged (named, with the fix)."""


@dataclass(frozen=True)
class Figure:
    """Ours over `n` independent units: mean and population std; per-unit `values` (keyed
    by seed, fold, dataset or run, for pairing) where the records keep them; `given` an
    interval the folder computed itself (a bootstrap over samples) where there are no units."""

    mean: float
    std: float
    n: int
    values: dict[str, float] | None = None
    given: tuple[float, float] | None = None
    fmt: str = ".1f"
    unit: str = ""
    ratio: float = 0.0          # n_test / n_train where the units are overlapping folds

    @classmethod
    def of(cls, values: dict[str, float], fmt: str = ".1f", unit: str = "",
           ratio: float = 0.0) -> Figure:
        ms = stats.mean_std(list(values.values()))
        return cls(ms["mean"], ms["std"], ms["n"], dict(values), None, fmt, unit,  # type: ignore[arg-type]
                   ratio)

    def interval(self) -> tuple[float, float] | None:
        return self.given or stats.t_interval(self.mean, self.std, self.n, ratio=self.ratio)

    def minus(self, other: Figure | float) -> Figure:
        """Self − other: paired per unit where both keep values for ≥ 2 shared units."""
        if isinstance(other, Figure) and other.n == 1 and other.std == 0:
            other = other.mean          # one deterministic figure (the 2X heuristic): a number
        if not isinstance(other, Figure):
            lo_hi = self.given and (self.given[0] - other, self.given[1] - other)
            values = self.values and {k: v - other for k, v in self.values.items()}
            return replace(self, mean=self.mean - other, values=values, given=lo_hi)
        if self.values and other.values:
            shared = [k for k in self.values if k in other.values]
            if len(shared) >= 2:
                return Figure.of({k: self.values[k] - other.values[k] for k in shared},
                                 self.fmt, self.unit, max(self.ratio, other.ratio))
        raise _Unpaired

    def text(self, digits: str | None = None) -> str:
        fmt = digits or self.fmt
        if self.n == 0:                 # a number of the text's (a threshold), not ours
            return f"{self.mean:{fmt}}"
        unit = f" {self.unit}" if self.unit else ""
        ci = self.interval()
        spread = f" [{ci[0]:{fmt}}, {ci[1]:{fmt}}]" if ci else ""
        units = "" if self.given else f", n {self.n}"   # a folder's interval is over samples
        return f"{self.mean:{fmt}}{unit}{spread}{units}"


@dataclass(frozen=True)
class Design:
    """What a folder's runs are as evidence, declared in `results/index.toml` (a claim may
    override any key): `unit` the independent unit (seed, fold, dataset, split, test
    instance); `within` a unit nested in it, whose runs are averaged to the outer unit found
    in each run's key by the regex `group`; `folds` the count of cross-validated folds whose
    training sets overlap (Nadeau-Bengio corrected); `split_ratio` n_test/n_train of random
    train/test splits resampled from one pool, whose training sets overlap too (corrected
    alike); `shared` what every unit shares, said beside the number; `trainings` 1 where the
    figure is one training's."""

    unit: str
    within: str = ""
    group: str = ""
    folds: int = 0
    split_ratio: float = 0.0
    shared: str = ""
    trainings: int = 0

    KEYS = ("unit", "within", "group", "folds", "split_ratio", "shared", "trainings")

    @classmethod
    def of(cls, entry: dict, where: str) -> Design:
        if not entry.get("unit"):
            raise ClaimsError(f"{where} declares no `unit`: name what is independent (seed, "
                              "fold, dataset, split or test instance) in results/index.toml")
        if bool(entry.get("within")) != bool(entry.get("group")):
            raise ClaimsError(f"{where}: `within` and `group` come together (the nested unit "
                              "and the regex that finds its outer unit in a run's key)")
        return cls(**{k: entry[k] for k in cls.KEYS if k in entry})

    @property
    def ratio(self) -> float:
        return stats.cv_ratio(self.folds) if self.folds else self.split_ratio

    def correction(self) -> str:
        """The correction as `claims --json` and the pages name it."""
        if self.folds:
            return (f"Nadeau-Bengio corrected resampled t over {self.folds} overlapping folds "
                    f"(n_test/n_train = 1/{self.folds - 1})")
        if self.split_ratio:
            return ("Nadeau-Bengio corrected resampled t over random splits whose training "
                    f"sets overlap (n_test/n_train = {self.split_ratio:.3g})")
        return "none: independent units, Student's t"

    def apply(self, fig: Figure) -> Figure:
        """`fig` over this design's units: nested runs averaged to their outer unit, the
        folds' correction attached. A folder's own interval (a bootstrap) is left as it is."""
        if fig.given or fig.n == 0:
            return fig
        if self.within:
            if not fig.values:
                raise ClaimsError(f"runs nested in {self.unit}s need each run's value to "
                                  "average them, and this record keeps only a mean")
            groups: dict[str, list[float]] = {}
            for key, value in fig.values.items():
                match = re.search(self.group, key)
                if not match:
                    raise ClaimsError(f"run {key!r} names no {self.unit} ({self.group!r})")
                groups.setdefault(match[0], []).append(value)
            fig = Figure.of({k: sum(v) / len(v) for k, v in groups.items()}, fig.fmt, fig.unit)
        return replace(fig, ratio=self.ratio)

    def says(self, n: int | None) -> str:
        """Beside a number: its units, how runs nest in them, the correction, what is shared."""
        if self.trainings == 1 or n is None:
            what = f"one training; interval over {self.unit}s" if self.trainings == 1 else ""
        else:
            what = f"{self.unit}s" if n != 1 else self.unit
            if self.within:
                what += f", {self.within}s averaged within each"
            if self.folds or self.split_ratio:
                what += ", Nadeau-Bengio corrected"
        return "; ".join(p for p in (what, f"all share {self.shared}" if self.shared else "")
                         if p)


class _Unpaired(Exception):
    """Two figures without shared per-unit values: compared unpaired (Welch)."""


SOURCES: dict[str, Callable[..., Figure]] = {}


def source(fn: Callable[..., Figure]) -> Callable[..., Figure]:
    """Register a function claims may name."""
    SOURCES[fn.__name__] = fn
    return fn


# Reading the results folders ------------------------------------------------------------------

@cache
def _load(file: Path) -> object:
    if not file.is_file():
        raise ClaimsError(f"{file} does not exist: run the command results/index.toml gives for "
                          "its folder, or pass --results with a checkout's results/ folder")
    try:
        return json.loads(file.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ClaimsError(f"cannot read {file}: {exc}; rerun its folder's command") from exc


def dig(data: object, keypath: str) -> object:
    """`a/b/0/c` into nested dicts and lists."""
    for key in filter(None, keypath.split("/")):
        data = data[int(key)] if isinstance(data, list) else data[key]  # type: ignore[index]
    return data


_ROOTS: list[Path] = []          # the results folder `judge_all` is judging, for the sources


def _root() -> Path:
    return _ROOTS[-1]


def _json(path: str) -> object:
    """A JSON file under the results folder being judged, read once."""
    return _load(_root() / path)


def _meanstd(d: dict, scale: float = 1.0, fmt: str = ".1f", unit: str = "") -> Figure:
    return Figure(float(d["mean"]) * scale, float(d["std"]) * scale, int(d["n"]), None, None,
                  fmt, unit)


# Sources -------------------------------------------------------------------------------------

@source
def runs(pattern: str, keypath: str, fmt: str = ".1f", unit: str = "", scale: str = "1") -> Figure:
    """One number of each run folder matching `pattern` (a glob under results/, one run a seed)."""
    files = sorted(_root().glob(pattern))
    if not files:
        raise ClaimsError(f"no results/{pattern}: run the command results/index.toml gives")
    return Figure.of({f.parent.name: float(dig(_load(f), keypath)) * float(scale)
                      for f in files}, fmt, unit)


@source
def ratio(numerator: str, denominator: str, scale: str = "100", offset: str = "-100") -> Figure:
    """scale × a / b + offset per shared unit of two `runs` sources written `pattern|keypath`."""
    a, b = (runs(*side.split("|")) for side in (numerator, denominator))
    assert a.values is not None and b.values is not None
    return Figure.of({k: float(scale) * a.values[k] / b.values[k] + float(offset)
                      for k in a.values if k in b.values}, ".0f", "%")


def _retlo(folder: str, test: str) -> dict:
    return dig(_json(f"{folder}/results.json"), f"results/{test}")  # type: ignore[return-value]


@source
def retlo_error(folder: str, test: str, model: str) -> Figure:
    """A ReTLo model's mean error (cm) per fold-seed on a test of `experiment retlo`."""
    per = _retlo(folder, test)[model]["per_seed_cm"]
    return Figure.of({f"seed{i}": float(v) for i, v in enumerate(per)}, ".1f", "cm")


@source
def retlo_gain(folder: str, test: str) -> Figure:
    """Fig 2.7: how much lower the LSTM's error is than FC's (%), per fold-seed (paired)."""
    lstm, fc = (retlo_error(folder, test, m).values for m in ("lstm", "fc"))
    assert lstm is not None and fc is not None
    return Figure.of({k: 100 * (1 - lstm[k] / fc[k]) for k in lstm}, ".0f", "%")


@source
def retlo_step(folder: str, test: str, model: str, robot: str, step: str) -> Figure:
    """Fig 2.8: a model's error (cm) on one robot at the k-th step (1-based), over seeds."""
    cell = _retlo(folder, test)[model]["per_robot_step_cm"][robot][int(step) - 1]
    return _meanstd(cell, 1.0, ".1f", "cm")


@source
def meanstd(path: str, keypath: str, fmt: str = ".3f", unit: str = "", scale: str = "1",
            n: str = "") -> Figure:
    """A `{mean, std, n}` object of a results file (`n` given where the file omits it)."""
    d = dict(dig(_json(path), keypath))  # type: ignore[call-overload]
    if n:
        d["n"] = int(n)
    return _meanstd(d, float(scale), fmt, unit)


def _srs_models(folder: str) -> dict[tuple[str, int, int, int], dict]:
    out = {}
    for file in sorted((_root() / folder / "models").glob("*.json")):
        match = re.fullmatch(r"(.+)_b(\d+)_d(\d+)_m(\d+)", file.stem)
        if match:
            out[(match[1], int(match[2]), int(match[3]), int(match[4]))] = _load(file)
    if not out:
        raise ClaimsError(f"results/{folder}/models holds no model reports")
    return out


def _srs(folder: str, config: str, budget: str, pick: Callable[[dict], float]) -> Figure:
    percent = round(100 * float(budget))
    got = {f"d{d}m{m}": pick(rep) for (c, b, d, m), rep in _srs_models(folder).items()
           if c == config and b == percent}
    if not got:
        raise ClaimsError(f"results/{folder} has no {config} models at {percent} % of the budget")
    return Figure.of(got, ".1f", "cm")


@source
def srs(folder: str, config: str, budget: str, robot: str = "") -> Figure:
    """Chapter 3: a configuration's error (cm) at a budget share, all predictions (or one
    robot's), per model (dataset × model seed, paired across configurations)."""
    return _srs(folder, config, budget, lambda r: float(
        r["per_robot_cm"][robot] if robot else r["mean_error_cm"]))


@source
def srs_step(folder: str, config: str, robot: str, step: str) -> Figure:
    """Chapter 3, Fig 3.6: one robot's error (cm) at the k-th prediction, full budget."""
    return _srs(folder, config, "1", lambda r: float(
        r["per_robot_step_cm"][robot][int(step) - 1]))


@source
def srs_quantile(folder: str, config: str, pair: str, q: str, datasets: str = "3") -> Figure:
    """Chapter 3, Fig 3.7: a distance's `q` quantile (cm) per dataset (the results file keeps
    the datasets' distances one after another, in equal parts)."""
    import numpy as np

    values = np.asarray(dig(_json(f"{folder}/results.json"), f"distances/{config}/{pair}"))
    parts = np.split(values, int(datasets))
    return Figure.of({f"d{j}": float(np.quantile(p, float(q))) for j, p in enumerate(parts)},
                     ".1f", "cm")


def _oc_runs(folder: str, m: str) -> dict[str, dict]:
    runs_ = dig(_json(f"{folder}/results.json"), "runs")
    got = {key.split("_", 1)[1]: run for key, run in runs_.items()  # type: ignore[union-attr]
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


@source
def share(path: str, keypath: str) -> Figure:
    """A `{share, lo, hi, samples}` object (%): a folder's own bootstrap interval over samples."""
    d = dig(_json(path), keypath)
    return Figure(100 * float(d["share"]), 0.0, int(d["samples"]), None,  # type: ignore[index]
                  (100 * float(d["lo"]), 100 * float(d["hi"])), ".1f", "%")  # type: ignore[index]


def parse(expression: str) -> tuple[str, list[str]]:
    """`name(arg, arg, ...)` with bare-word arguments (no quotes needed): the name and the
    arguments; ("", []) when it is not such an expression. The docs' sources use it too."""
    match = re.fullmatch(r"\s*(\w+)\((.*)\)\s*", expression, re.S)
    if not match:
        return "", []
    return match[1], [a.strip() for a in match[2].split(",")] if match[2].strip() else []


def call(expression: str) -> Figure:
    """Evaluate a claims source expression (`parse`)."""
    name, args = parse(expression)
    if name not in SOURCES:
        raise ClaimsError(f"not a claims source: {expression!r} (one of {sorted(SOURCES)})")
    try:
        return SOURCES[name](*args)
    except (KeyError, IndexError, TypeError) as exc:
        raise ClaimsError(f"{expression}: the results hold no {exc}") from exc


# Judging -------------------------------------------------------------------------------------

@dataclass
class Comparison:
    """One `left op right` of an ordering claim, where right is a source or a number."""

    left: Figure
    op: str
    right: Figure | float
    label: str = ""

    def other(self, ours: Figure | None) -> Figure:
        """The side that is not `ours` (a number as a figure of its own)."""
        side = self.left if self.right is ours else self.right
        return side if isinstance(side, Figure) else Figure(side, 0.0, 0, fmt="g")

    def test(self) -> tuple[float | None, float | None, Figure | None]:
        """(p of the text's order, p of the reverse, the difference signed so the text's order
        is positive: per unit where paired, else the Welch spread, to size a decision)."""
        sign = 1.0 if self.op == ">" else -1.0
        try:
            diff = self.left.minus(self.right)
        except _Unpaired:
            r = self.right
            assert isinstance(r, Figure)
            # overlapping folds: the std that gives the corrected standard error at n units
            a, b = ((f.mean, f.std * (1 + f.n * f.ratio) ** 0.5, f.n) for f in (self.left, r))
            hi, lo = (a, b) if sign > 0 else (b, a)
            spread = Figure(hi[0] - lo[0], (a[1] ** 2 + b[1] ** 2) ** 0.5, min(a[2], b[2]))
            return stats.p_above_welch(hi, lo), stats.p_above_welch(lo, hi), spread
        if diff.given:                  # a folder's own interval: decided by where it lies
            lo, hi = sorted((sign * diff.given[0], sign * diff.given[1]))
            return (0.0 if lo > 0 else 1.0), (0.0 if hi < 0 else 1.0), None
        d = replace(diff, mean=sign * diff.mean)
        return (stats.p_above(d.mean, d.std, d.n, d.ratio),
                stats.p_above(-d.mean, d.std, d.n, d.ratio), d)


@dataclass
class Judged:
    """One claim judged: what `claims --json` prints per row."""

    chapter: str
    figure: str
    claim: str
    text: str
    text_value: float | None
    ours: float | None
    lo: float | None
    hi: float | None
    n: int | None
    kind: str
    verdict: str
    folder: str | None
    ours_text: str = ""
    comparator: str = ""
    why: str = ""
    would_decide: int | None = None
    smoke: bool = False
    finding: str = ""
    unit: str = ""
    correction: str = ""
    margin: str = ""
    extra: dict = field(default_factory=dict)

    def as_json(self) -> dict:
        keys = ("chapter", "figure", "claim", "text", "text_value", "ours", "lo", "hi", "n",
                "unit", "correction", "margin", "kind", "verdict", "folder", "comparator", "why",
                "would_decide", "smoke")
        return {k: getattr(self, k) for k in keys}


def margin_verdict(lo: float, hi: float, value: float, margin: float) -> str:
    """The two-sided margin rule: agree when [lo, hi] lies inside value ± margin, disagree
    when it lies wholly outside it, inconclusive when it straddles an edge."""
    if value - margin <= lo and hi <= value + margin:
        return "agree"
    if hi < value - margin or lo > value + margin:
        return "disagree"
    return "inconclusive"


def _value_verdict(ours: Figure, text_value: float, margin: float
                   ) -> tuple[str, str, int | None]:
    ci = ours.interval()
    if ci is None:
        return "inconclusive", "one unit: no spread to judge by", None
    verdict = margin_verdict(ci[0], ci[1], text_value, margin)
    band = (f"the text's {text_value:g} ± {margin:.2g} "
            f"([{text_value - margin:.3g}, {text_value + margin:.3g}])")
    if verdict == "agree":
        return verdict, f"our 95 % interval lies inside {band}", None
    if verdict == "disagree":
        return verdict, f"our 95 % interval lies wholly outside {band}", None
    # the units that would decide it at the observed spread: an interval narrow enough to
    # fit inside the band (mean inside it) or to clear it (mean outside it)
    room = margin - abs(ours.mean - text_value)
    would = stats.units_to_narrow(ours.std, ours.n, abs(room), ratio=ours.ratio)
    return verdict, f"our 95 % interval straddles an edge of {band}", would


def _order_verdict(comparisons: list[Comparison]) -> tuple[str, str, int | None]:
    k = len(comparisons)
    open_: list[tuple[str, Figure | None]] = []
    for c in comparisons:
        p_text, p_rev, diff = c.test()
        if p_text is not None and p_text < ALPHA:
            continue
        if p_rev is not None and p_rev < ALPHA / k:
            return "disagree", (f"{c.label or 'the comparison'}: the reverse order holds "
                                f"(p {p_rev:.2g}{'' if k == 1 else f' < .05/{k}'})"), None
        open_.append((c.label, diff))
    if not open_:
        return "agree", f"the text's order holds (p < .05{'' if k == 1 else f', all {k}'})", None
    # units that would decide it at the observed spread: the fewest that make one reverse
    # order significant (a disagree needs one), else the most any text-order one needs
    reverse = [stats.units_to_decide(-d.mean, d.std, d.n, ALPHA / k, ratio=d.ratio)
               for _, d in open_ if d is not None and d.mean < 0]
    ahead = [stats.units_to_decide(d.mean, d.std, d.n, ratio=d.ratio)
             if d is not None and d.mean > 0 else None for _, d in open_]
    would = (min((n for n in reverse if n), default=None) if reverse else
             max(ahead) if ahead and None not in ahead else None)  # type: ignore[type-var]
    if k == 1:
        return "inconclusive", "neither order rejected at p < .05", would
    names = ", ".join(label for label, _ in open_[:6]) + (" ..." if len(open_) > 6 else "")
    return "inconclusive", f"{len(open_)} of {k} undecided ({names})", would


def _side(spec: object, ours: Figure | None, design: Design) -> Figure | float:
    """A comparison's side: a number, `ours`, or a source over the claim's units."""
    if isinstance(spec, int | float):
        return float(spec)
    if spec == "ours":
        if ours is None:
            raise ClaimsError("an order row names `ours` but the claim has none")
        return ours
    return design.apply(call(str(spec)))


def _margin(claim: dict, text_value: float) -> tuple[float, str]:
    """A value claim's margin and where it comes from: the row's own (with its reason) or its
    metric's (`MARGINS`)."""
    if "margin" in claim:
        return float(claim["margin"]), claim.get("margin_why", "the row's own")
    metric = claim.get("metric")
    if metric not in MARGINS:
        raise ClaimsError(f"{claim['figure']}: a value claim names its `metric` (one of "
                          f"{sorted(MARGINS)}) or its own `margin` with `margin_why`")
    absolute, share = MARGINS[metric]
    return absolute + share * abs(text_value), metric


def design_of(claim: dict, index: dict[str, dict]) -> Design:
    """The claim's units: its folder's declaration in results/index.toml, the claim's keys
    over it (one folder may hold tests of different designs)."""
    folder = claim.get("folder", "")
    entry = {k: v for k, v in index.get(folder, {}).items() if k in Design.KEYS}
    entry |= {k: claim[k] for k in Design.KEYS if k in claim}
    return Design.of(entry, f"results/{folder} ({claim['figure']})")


def judge(chapter: str, claim: dict, smoke_folders: frozenset[str] = frozenset(),
          index: dict[str, dict] | None = None) -> Judged:
    """One claim of `claims.toml` judged by `RULE` over the units `index` declares."""
    kind = claim["kind"]
    design = design_of(claim, index or {})
    text_value = claim.get("text_value")
    if "text_from" in claim:            # a dissertation table kept in code: "0.786 ± 0.009"
        module, _, keypath = claim["text_from"].partition(":")
        claim = {**claim, "text": str(dig(vars(import_module(module)), keypath))}
        text_value = float(re.findall(r"[\d.]+", claim["text"])[0])
    ours = design.apply(call(claim["ours"])) if claim.get("ours") else None
    comparator, why, would, margin = claim.get("comparator_text", ""), "", None, ""
    if kind == "value":
        if ours is None or text_value is None:
            raise ClaimsError(f"{claim['figure']}: a value claim needs `ours` and `text_value`")
        size, source_ = _margin(claim, float(text_value))
        margin = f"± {size:.3g} ({source_})"
        verdict, why, would = _value_verdict(ours, float(text_value), size)
    elif kind == "ordering":
        comparisons = []
        first, last = claim.get("steps", [1, 1])
        rows = [[str(x).replace("{step}", str(k)) if isinstance(x, str) else x for x in row]
                for row in claim["order"] for k in range(first, last + 1)
                if k == first or any("{step}" in str(x) for x in row)]
        for left, op, right, *label in rows:
            comparisons.append(Comparison(_side(left, ours, design), op,  # type: ignore[arg-type]
                                          _side(right, ours, design),
                                          label[0] if label else ""))
        if ours is None:
            ours = comparisons[0].left
        verdict, why, would = _order_verdict(comparisons)
        if not comparator:
            comparator = "; ".join(f"{c.label or 'vs'}: {c.other(ours).text()}"
                                   for c in comparisons[:4]) + (
                " ..." if len(comparisons) > 4 else "")
    elif kind == "qualitative":
        verdict, why = "qualitative", claim["judged"]
    else:
        raise ClaimsError(f"{claim['figure']}: kind must be value, ordering or qualitative, "
                          f"not {kind!r}")
    if design.trainings == 1 and verdict in ("agree", "disagree"):
        verdict, why, would = ("inconclusive", f"one training (one seed): the rule would say "
                               f"{verdict} ({why}), but one seed's figure moves with the seed "
                               f"and the machine ({MACHINES}), beyond any margin here", None)
    if claim.get("not_comparable"):     # judged all the same, so a reader sees what ours says
        verdict, why, would = ("not comparable", f"{claim['not_comparable']}; on ours the rule "
                               f"says {verdict} ({why})", None)
    ci = ours.interval() if ours is not None else None
    folder = claim.get("folder")
    return Judged(chapter, claim["figure"], claim["claim"], claim.get("text", ""),
                  None if text_value is None else float(text_value),
                  None if ours is None else ours.mean, ci[0] if ci else None,
                  ci[1] if ci else None, None if ours is None else ours.n, kind, verdict,
                  folder, "" if ours is None else _beside(ours, design), comparator, why,
                  would, folder in smoke_folders, claim.get("finding", ""),
                  unit=design.says(None if ours is None else ours.n) or design.unit,
                  correction=design.correction(), margin=margin)


def _beside(ours: Figure, design: Design) -> str:
    """Ours as a row shows it: the number, its interval and n, and its units beside them."""
    says = design.says(ours.n)
    return ours.text() + (f" ({says})" if says else "")


def load_claims(path: Path = CLAIMS) -> dict[str, list[dict]]:
    """The claims, chapter by chapter."""
    try:
        return tomllib.loads(path.read_text())
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise ClaimsError(f"cannot read {path}: {exc}") from exc


def judge_all(results: Path, chapters: list[str] | None = None,
              claims_file: Path = CLAIMS) -> list[Judged]:
    """Every claim (of `chapters`, default all) judged on the folders under `results`."""
    if not (results / "index.toml").is_file():
        raise ClaimsError(f"{results} is not a results folder (no index.toml): pass --results "
                          "with a checkout's results/ folder")
    from macrostate_mj.app.provenance import read_index, smoke_folders

    claims = load_claims(claims_file)
    unknown = sorted(set(chapters or []) - set(claims))
    if unknown:
        raise ClaimsError(f"no chapter {unknown[0]!r} in the claims: one of {sorted(claims)}")
    _ROOTS.append(results.resolve())
    try:
        smoke = smoke_folders(results)
        index = read_index(results)
        return [judge(ch, c, smoke, index) for ch in (chapters or list(claims))
                for c in claims[ch]]
    finally:
        _ROOTS.pop()


def counts(judged: list[Judged]) -> dict[str, int]:
    """How many claims each verdict has (every verdict named, zeros kept)."""
    return {v: sum(j.verdict == v for j in judged) for v in VERDICTS}
