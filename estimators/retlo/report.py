"""How both chapters measure a chain estimate: which robots count (the ones the Tail cannot
see), their names in reports, and the reports themselves.

Chapter 3's report (`evaluate_chain`) is in cm, the unit of its figures (Fig 2.7-2.8, §3.5);
chapter 2's (`summarize`) in metres against the robot diameter, as Fig 2.2.
"""

from __future__ import annotations

import warnings

import numpy as np

from estimators.retlo import CM_PER_M
from estimators.retlo.chain import Module, first_estimate, predict_chain, true_windows
from estimators.retlo.frames import decode
from estimators.retlo.gaussian import GAUSSIAN_REGIONS, Regions, calibration
from macrostate_mj.formats.thymioloc import STEP_S, robot_names


def report_names(n_robots: int) -> list[str]:
    """Names in reports, Tail first: Followers counted from the Tail as in §2.5.3.1 (F1 = the
    Tail's neighbour), so 5-robot reports read F2, F3, H as in Fig 2.7-2.8. ThymioLoc columns
    count from the Head, so report F_j is column F_{N-1-j}."""
    return ["T", *(f"F{j}" for j in range(1, n_robots - 1)), "H"]


def chain_positions(n_robots: int) -> np.ndarray:
    """Each robot's chain position in file order (Head first), the index `gaussian.Regions`
    keeps radii by: position j is robot j + 2 from the Tail, the robot module j estimates
    (file column N-3-j). The Tail and its neighbour, never estimated, get 0."""
    return np.clip(n_robots - 3 - np.arange(n_robots), 0, None)


def unseen_names(n: int) -> list[str]:
    """Names of robots 2.. (Tail first), as the reports of both chapters call them."""
    return report_names(n)[2:]


def unseen_errors(est_xy: np.ndarray, truth_xy: np.ndarray) -> np.ndarray:
    """Euclidean error (..., N-2) of robots 2.. (Tail first: the ones the Tail cannot see), from
    positions (..., N, 2); NaN where there is no estimate."""
    return np.linalg.norm(est_xy[..., 2:, :] - truth_xy[..., 2:, :], axis=-1)


def evaluate_chain(module: Module, world: np.ndarray) -> dict:
    """Errors (cm) of every robot the Tail cannot see in chains (B, S, N, 3) of true poses (m,
    rad, file order): per robot, per step, and their mean."""
    return chain_report(predict_chain(module, world), world, module.history)


def chain_report(est: np.ndarray, world: np.ndarray, history: int) -> dict:
    """`evaluate_chain`'s report of estimates `est` (`predict_chain`'s layout) made by a module
    with `history` steps."""
    n_robots, first = world.shape[2], first_estimate(history)
    names = report_names(n_robots)
    file_names = robot_names(n_robots)[::-1]
    unseen = CM_PER_M * unseen_errors(est[:, first:, ::-1, :2], world[:, first:, ::-1, :2])
    per_robot = {names[j]: float(np.nanmean(unseen[:, :, j - 2])) for j in range(2, n_robots)}
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN columns: steps out of reach
        step_means = np.nanmean(unseen, axis=0)  # (steps, robots)
    per_step = [None if np.all(np.isnan(row)) else float(np.nanmean(row)) for row in step_means]
    return {
        "mean_error_cm": float(np.nanmean(unseen)),
        "per_robot_cm": per_robot,
        "per_step_cm": per_step,
        "per_robot_step_cm": {names[j]: [None if np.isnan(v) else float(v)
                                         for v in step_means[:, j - 2]]
                              for j in range(2, n_robots)},
        "first_step": first,
        "step_s": STEP_S,
        "n_instances": int(world.shape[0]),
        "n_robots": n_robots,
        "csv_robot": {names[j]: file_names[j] for j in range(2, n_robots)},
    }


def calibration_report(est: np.ndarray, cov: np.ndarray, world: np.ndarray, history: int,
                       regions: Regions = GAUSSIAN_REGIONS) -> dict:
    """Calibration (`gaussian.calibration`, positions in cm) of Gaussian estimates (est, cov in
    `propagate.predict_chain_gaussian`'s layout) of every robot the Tail cannot see, per robot
    (report names) and pooled, of the model's `regions`."""
    first = first_estimate(history)
    names = report_names(world.shape[2])
    x = CM_PER_M * world[:, first:, ::-1, :2][:, :, 2:]
    mean = CM_PER_M * est[:, first:, ::-1, :2][:, :, 2:]
    cov_cm = CM_PER_M ** 2 * cov[:, first:, ::-1][:, :, 2:]
    per = {names[j + 2]: calibration(x[:, :, j], mean[:, :, j], cov_cm[:, :, j], regions, j)
           for j in range(x.shape[2])}
    position = np.arange(x.shape[2])          # robot j (Tail side first) is chain position j
    return {**per, "pooled": calibration(x, mean, cov_cm, regions, position), "nll_unit": "cm"}


def chain_errors(est: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """Euclidean error (S, N-2) of every robot the Tail cannot see (robots 2.., Tail first),
    NaN at τ and where no estimate exists (the last steps of far robots)."""
    err = unseen_errors(est, truth[..., :2])
    err[0] = np.nan
    return err


def one_step_errors(module: Module, truth: np.ndarray) -> np.ndarray:
    """Error (S - ℓ - 1,) of robot 2 when module 0 gets true inputs at every step (true θ_F, no
    recursion), truth (S, N, 3) Tail first: separates what the module gets wrong from what the
    recursion accumulates."""
    win = true_windows(truth[None], 0, module.history, module.rotate)
    est = decode(module.estimate(module.features(win)), win.origin, win.alpha)
    return np.linalg.norm(est.head_xy - truth[module.history:-1, 2, :2], axis=-1)


def summarize(err: np.ndarray, names: list[str], threshold: float) -> dict:
    """Per robot and overall: mean error and the share of steps under `threshold`."""
    def stats(e: np.ndarray) -> dict:
        e = e[np.isfinite(e)]
        return {"mean_error": float(e.mean()), "max_error": float(e.max()),
                "share_under": float((e < threshold).mean()), "steps": int(e.size)}

    return {"per_robot": {nm: stats(err[:, j]) for j, nm in enumerate(names)},
            "all": stats(err.ravel())}
