"""The dissertation's claims judged on the committed results by one rule (`RULE`).

`claims.toml` beside this module gives per claim the text's value or order, where ours lives in
a results folder (a *source* expression such as ``srs(srs_text, passive, 1.0000)``) and its kind.
Every source it names (one registry with the docs', `app.results.sources`, each beside the
experiment whose record it reads) returns a `Figure`: ours per run, with per-run values
where the records keep them so that orderings pair them. What is independent is declared
beside the results, not guessed from the run count: each folder's entry of
`results/index.toml` (a claim may override it) names its unit and how units nest (`Design`),
and `judge` averages nested runs to that unit and corrects overlapping folds before any
interval is drawn. The `claims` command and the docs' chapter pages
both call `judge_all`, so they cannot differ.
"""

from __future__ import annotations

import re
import tomllib
from dataclasses import dataclass, field, replace
from importlib import import_module
from pathlib import Path

from macrostate_mj.app.results import CLAIMS
from macrostate_mj.app.results.sources import call, reading
from macrostate_mj.core import stats
from macrostate_mj.core.evidence import ClaimsError, Design, Figure, Unpaired, dig

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
        except Unpaired:
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
    return design.apply(_ours(str(spec)))


def _ours(expression: str) -> Figure:
    """A source's figure of ours, over units it counts (a page may show a mean and spread a
    file keeps without its count; a claim may not judge one)."""
    fig = call(expression)
    if not isinstance(fig, Figure) or fig.n == 0:
        raise ClaimsError(f"{expression}: not a figure over counted units (a source of claims "
                          "returns a Figure whose records keep n)")
    return fig


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
    ours = design.apply(_ours(claim["ours"])) if claim.get("ours") else None
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
    from macrostate_mj.app.results.provenance import read_index, smoke_folders

    claims = load_claims(claims_file)
    unknown = sorted(set(chapters or []) - set(claims))
    if unknown:
        raise ClaimsError(f"no chapter {unknown[0]!r} in the claims: one of {sorted(claims)}")
    with reading(results):
        smoke = smoke_folders(results)
        index = read_index(results)
        return [judge(ch, c, smoke, index) for ch in (chapters or list(claims))
                for c in claims[ch]]


def counts(judged: list[Judged]) -> dict[str, int]:
    """How many claims each verdict has (every verdict named, zeros kept)."""
    return {v: sum(j.verdict == v for j in judged) for v in VERDICTS}
