"""`experiment retlo`'s tables, numbers and claims' figures, read through its record."""

from __future__ import annotations

from macrostate_mj.app.experiments.retlo.record import CV_TEST, Results
from macrostate_mj.app.results.sources import (
    load,
    record,
    source,
    stat,
)
from macrostate_mj.core.evidence import Code, Figure, Table
from macrostate_mj.core.run import MANIFEST


@source
def retlo_models(folder: str) -> Table:
    """Fig 2.7: each model's mean error (cm) per test set and robot, mean ± std over seeds."""
    data = record(Results, folder)
    rows = [["test set", "robots", "model", "mean error (cm)", "per robot (cm)"]]
    for test in data.tests:
        for model, agg in data.results[test["name"]].items():
            per = "; ".join(f"{r} {stat(v, '.1f')}" if isinstance(v, dict) else f"{r} {v:.1f}"
                            for r, v in agg["per_robot_cm"].items())
            rows.append([test["name"], str(test["n_robots"]), model,
                         stat(agg["mean_error_cm"], ".1f") if isinstance(agg["mean_error_cm"],
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

    runs = [(record(Results, f), load(f"{f}/{MANIFEST}")["config"])
            for f in folders]
    tests = [t["name"] for t in runs[0][0].tests]
    rows = [["training", "model", *tests, "per fold (cross-validated)",
             "folds better than the first"]]
    for i, (data, config) in enumerate(runs):
        label = "split" if config.get("split") else \
            "chained" if config.get("chained", True) else "not chained"
        if config.get("precision", "fp32") != "fp32":
            label += f", {config['precision']}"
        for model in MODEL_KINDS:
            cells = [stat(data.results[t][model]["mean_error_cm"], ".2f") for t in tests]
            per = data.results.get(CV_TEST, {}).get(model, {}).get("per_seed_cm", [])
            first = runs[0][0].results.get(CV_TEST, {}).get(model, {}).get("per_seed_cm", [])
            better = sum(a < b for a, b in zip(per, first, strict=True))
            rows.append([Code(label), model, *cells,
                         " ".join(f"{v:.2f}" for v in per),
                         f"{better} / {len(per)}" if i and per else ""])
    return rows


@source
def retlo_calibration(folder: str) -> Table:
    """Gaussian ReTLo models of `experiment retlo --uncertainty gaussian`: per test set, model
    and robot (and pooled), the share of true positions inside the 50 % and 90 % regions and
    the NLL, mean ± std over seeds; where the models carry fitted region radii, the coverage
    of the plain Gaussian's χ² regions beside."""
    data = record(Results, folder)
    head = ["test set", "model", "robot", "coverage 50 %", "coverage 90 %"]
    rows: Table = []
    for test in data.tests:
        for model, agg in data.results[test["name"]].items():
            for who, cal in agg.get("calibration", {}).items():
                plain = [stat(cal[k], ".2f") for k in ("gaussian_coverage_50",
                                                        "gaussian_coverage_90") if k in cal]
                rows.append([test["name"], model, who, stat(cal["coverage_50"], ".2f"),
                             stat(cal["coverage_90"], ".2f"), *plain, stat(cal["nll"], ".2f")])
    fitted = bool(rows) and len(rows[0]) > 6
    return [head + (["Gaussian χ² 50 %", "Gaussian χ² 90 %"] if fitted else []) + ["NLL"],
            *rows]


@source
def retlo_fig29(folder: str) -> Table:
    """Fig 2.9: the inside-of-curve bias (cm) and the largest-error share per robot and model."""
    data = record(Results, folder).fig2_9
    rows = [["model", "robot", "toward the inside (cm)", "curved steps",
             "instants it errs most (%)"]]
    for model in ("fc", "lstm"):
        part = data[model]
        for robot, inside in part["inside_cm"].items():
            share = part["largest_error_share"].get(robot)
            rows.append([model, robot, stat(inside, ".2f"), str(part["curved_steps"][robot]),
                         stat(share, ".0f", 100) if share else ""])
    return rows


def _retlo(folder: str, test: str) -> dict:
    return record(Results, folder).results[test]


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
    return Figure(float(cell["mean"]), float(cell["std"]), int(cell["n"]), None, None, ".1f",
                  "cm")

