"""`experiment srs`'s tables, numbers and claims' figures, read through its record and its
models' reports."""

from __future__ import annotations

import re
import statistics
from collections.abc import Callable

from macrostate_mj.app.experiments.srs.record import Results
from macrostate_mj.app.results.sources import (
    ms,
    read_path,
    record,
    root,
    source,
    stat,
)
from macrostate_mj.core.evidence import ClaimsError, Figure, Q, Table


@source
def srs_cell(folder: str, config: str, budget: str, metric: str) -> Q:
    """Chapter 3: one configuration's error (cm) at a budget share (`1.0000`, `0.6667`, ...),
    mean ± std over its datasets and model seeds."""
    cell = record(Results, folder).configs[config][budget][metric]
    return Q(float(cell["mean"]), float(cell["std"]), ".1f", "cm")


@source
def srs_table(folder: str, metric: str) -> Table:
    """Chapter 3: per configuration, the error (cm) at each budget share of the largest."""
    data = record(Results, folder)
    configs = data.configs
    budgets = sorted({b for c in configs.values() for b in c}, key=float)
    rows = [["configuration", *[f"{float(b) * 100:.0f} % of budget" for b in budgets]]]
    for name, by_budget in configs.items():
        rows.append([name, *[stat(by_budget[b][metric], ".1f") if b in by_budget else ""
                             for b in budgets]])
    return rows


def _srs_errors(folder: str) -> dict[tuple[str, int, int, int], float]:
    """The error of all predictions (cm) of each of a chapter-3 folder's models (`_srs_models`)."""
    return {key: float(rep["mean_error_cm"]) for key, rep in _srs_models(folder).items()}


@source
def srs_pairs(base: str, other: str, spread: str = "") -> Table:
    """Two chapter-3 folders on their common models (same configuration, budget, dataset and
    model seed): per configuration and budget the error of all predictions (cm) of the paired
    models in each, and their mean difference (other - base); then every distinct pair's
    difference beside the model seed-to-seed differences (seeds 1, 2 - seed 0) of `spread`'s
    (default: base's) models of those configurations and budgets."""
    a, b = _srs_errors(base), _srs_errors(other)
    shared = [key for key in b if key in a]
    cells = sorted({key[:2] for key in shared})
    rows = [["configuration", "budget %", base, other, "mean difference"]]
    for config, budget in cells:
        keys = [k for k in shared if k[:2] == (config, budget)]
        rows.append([config, str(budget), ms([a[k] for k in keys], ".2f"),
                     ms([b[k] for k in keys], ".2f"),
                     f"{statistics.fmean(b[k] - a[k] for k in keys):+.2f}"])
    s = _srs_errors(spread or base)
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


def _srs_models(folder: str) -> dict[tuple[str, int, int, int], dict]:
    """A chapter-3 folder's per-model reports (`models/<config>_b<budget>_d<j>_m<i>.json`), by
    (configuration, budget %, dataset, model seed)."""
    out = {}
    for file in sorted((root() / folder / "models").glob("*.json")):
        match = re.fullmatch(r"(.+)_b(\d+)_d(\d+)_m(\d+)", file.stem)
        if match:
            out[(match[1], int(match[2]), int(match[3]), int(match[4]))] = read_path(file)
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

    values = np.asarray(record(Results, folder).distances[config][pair])
    parts = np.split(values, int(datasets))
    return Figure.of({f"d{j}": float(np.quantile(p, float(q))) for j, p in enumerate(parts)},
                     ".1f", "cm")

