"""What a number on a results page or in a claim's verdict is: a quantity (`Q`), ours over
independent units (`Figure`), what a folder's runs are as evidence (`Design`), a paired
difference over those units (`Paired`) and a table (`Table`).

Every results source returns one of these: a page prints it, a claim's verdict judges a
`Figure` by one rule. They hold no results layout of their own: that is each record's.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, replace

from macrostate_mj.core import stats
from macrostate_mj.core.errors import UserError
from macrostate_mj.core.records import UNITS


@dataclass(frozen=True)
class Code:
    """A table cell shown as code (a folder, a file, a parameter group), optionally followed
    by plain text (`tail`)."""

    text: str
    tail: str = ""

    def astext(self) -> str:
        return self.text + self.tail

    def __str__(self) -> str:
        return self.astext()


Table = list[list]    # rows of cells (text, or `Code`), the first the header


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
        raise Unpaired

    def __str__(self) -> str:
        """As a page prints a `{mean, std}` figure: `mean ± std unit`."""
        return str(Q(self.mean, self.std, self.fmt, self.unit))

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
            raise ClaimsError(f"{where} declares no `unit`: name what is independent (one of "
                              f"{', '.join(UNITS)}) in results/index.toml")
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


class Unpaired(Exception):
    """Two figures without shared per-unit values: compared unpaired (Welch)."""


def dig(data: object, keypath: str) -> object:
    """`a/b/0/c` into nested dicts and lists."""
    for key in filter(None, keypath.split("/")):
        data = data[int(key)] if isinstance(data, list) else data[key]  # type: ignore[index]
    return data




@dataclass(frozen=True)
class Paired:
    """A paired difference over the independent units of its runs: its mean and 95 % t
    interval over them, the units named beside it, and what it decides."""

    mean: float
    low: float
    high: float
    n: int
    units: str
    fmt: str = ".2f"
    unit: str = ""

    @classmethod
    def of(cls, differences: dict[str, float], plan: Design, keys: dict[str, str],
           where: str, fmt: str = ".2f", unit: str = "") -> Paired:
        """Per-seed differences (keyed by seed) over `plan`'s units (`keys`: each seed's key,
        where `Design.apply` finds its unit): seeds that share a fold averaged to it and
        overlapping folds corrected, the interval `Figure.interval`'s: what the claims draw."""
        fig = plan.apply(Figure.of({keys[s]: d for s, d in differences.items()}))
        ci = fig.interval()
        if ci is None:
            raise ValueError(f"{where}: one {plan.unit}, no interval to draw")
        return cls(fig.mean, ci[0], ci[1], fig.n, f"{fig.n} {plan.says(fig.n)}", fmt, unit)

    def __str__(self) -> str:
        each = self.units.split(" ", 1)[1].split(",")[0].removesuffix("s")
        verdict = (f"equal on every {each}" if self.low == self.high == 0 else
                   "inconclusive" if self.low <= 0 <= self.high else "decided")
        f, u = self.fmt, f" {self.unit}" if self.unit else ""
        return (f"{self.mean:+{f}}{u} [{self.low:+{f}}, {self.high:+{f}}], {self.units}: "
                f"{verdict}")
