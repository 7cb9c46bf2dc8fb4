"""Modular chain inference (§2.5.1.2) and its evaluation: one 3-robot module, any chain length.

Robots are indexed from the Tail here (0 = Tail, 1 = its observed neighbour, ..., N-1 = Head);
ThymioLoc files list them from the Head. Module k takes robot k as its reference (real or
fictitious Tail), robot k+1 as its Follower and predicts robot k+2. Module k needs robot k+1 at
t+1, which module k-1 estimated one step later, so robot j is known up to step S-j (the linear
delay of §2.5.1.2); offline we simply run the modules in order over a whole instance.

Both chapters' modules share this schedule (`module_steps`), the names of the robots the Tail
cannot see (`report_names`) and how their error is measured (`unseen_errors`); what differs is
the module: chapter 3's (`predict_chain`) is fed ℓ steps of its own history over a batch of
instances, chapter 2's (`estimators.retlo_sim.estimate`) one step, with true poses at sync steps.
"""

from __future__ import annotations

import warnings

import numpy as np

from estimators.retlo.frames import module_inputs, module_targets
from estimators.retlo.models import Predictor
from macrostate_mj.core.angles import wrap_angle
from macrostate_mj.core.errors import UserError
from macrostate_mj.core.frames import from_frame
from macrostate_mj.formats.thymioloc import STEP_S, robot_names


def check_chain(shape: tuple[int, ...], history: int, what: str = "data") -> None:
    """Refuse chains the module cannot run on: fewer than 3 robots, or no step after the history."""
    _, n_steps, n_robots, _ = shape
    if n_robots < 3:
        raise UserError(f"{what} has {n_robots} robots; ReTLo needs chains of at least 3 "
                        "(Head, Follower, Tail)")
    if n_steps < history + 2:
        raise UserError(f"{what} has {n_steps} steps; the model needs at least {history + 2} "
                        f"({history} of history, then a step and the next observation)")


def module_steps(k: int, n_steps: int, first_step: int) -> range:
    """Steps module k estimates: from `first_step` until it runs out of input. Module k reads
    robot k+1 at t+1, which module k-1 estimated at its step t+1, so each module stops one step
    before the one below it (k steps before the end, less the step after t)."""
    return range(first_step, n_steps - 1 - k)


def unseen_errors(est_xy: np.ndarray, truth_xy: np.ndarray) -> np.ndarray:
    """Euclidean error (..., N-2) of robots 2.. (Tail first: the ones the Tail cannot see), from
    positions (..., N, 2); NaN where there is no estimate."""
    return np.linalg.norm(est_xy[..., 2:, :] - truth_xy[..., 2:, :], axis=-1)


def predict_chain(pred: Predictor, world: np.ndarray,
                  samples: dict[str, list[np.ndarray]] | None = None) -> np.ndarray:
    """Estimate every robot the Tail cannot see, from true poses until τ = ℓ-1 and afterwards only
    the Tail's own pose and its neighbour's position.

    world: (B, S, N, 3) in file order (H, F1.., T), cm and radians. Returns the estimates in the
    same layout: NaN where nothing is estimated (the Tail; the neighbour's position; steps < ℓ
    and the last steps a module cannot reach). Truth after τ is blanked before use, so a leak
    would surface as NaN rather than as a flattering error. If `samples` is given, the inputs
    actually fed to the module are appended to it with their true targets (for training on the
    model's own feedback, see `train`).
    """
    hist = pred.history
    check_chain(world.shape, hist)
    n_steps, n_robots = world.shape[1], world.shape[2]
    truth = world[:, :, ::-1].astype(np.float64)  # Tail first
    track = truth.copy()
    track[:, hist:, 2:] = np.nan  # unseen robots: unknown after τ
    track[:, hist:, 1, 2] = np.nan  # the neighbour's heading is not observed either
    est = np.full_like(track, np.nan)
    for k in range(n_robots - 2):
        ref, head = track[:, :, k], track[:, :, k + 2]
        fol = track[:, :, k + 1].copy()  # this module's own estimates of θ_F go in its history
        for t in module_steps(k, n_steps, hist):
            obs, x_hist, origin, alpha = module_inputs(
                ref, fol, head, t, hist, pred.cos_sin, hist if pred.mark_estimates else None,
                pred.rotate)
            pos, ang = pred.predict(obs, x_hist)
            if samples is not None:
                y_pos, y_ang = module_targets(truth[:, :, k + 1], truth[:, :, k + 2], t, origin,
                                              alpha)
                for key, val in zip(("obs", "hist", "pos", "ang"), (obs, x_hist, y_pos, y_ang),
                                    strict=True):
                    samples.setdefault(key, []).append(val)
            head[:, t, :2] = from_frame(pos, origin, alpha)
            head[:, t, 2] = wrap_angle(ang[:, 1] + alpha)
            fol[:, t, 2] = wrap_angle(ang[:, 0] + alpha)
            if k == 0:
                est[:, t, 1, 2] = fol[:, t, 2]
        est[:, hist:, k + 2] = head[:, hist:]
    return est[:, :, ::-1]


def report_names(n_robots: int) -> list[str]:
    """Names in reports, Tail first: Followers counted from the Tail as in §2.5.3.1 (F1 = the
    Tail's neighbour), so 5-robot reports read F2, F3, H as in Fig 2.7-2.8. ThymioLoc columns
    count from the Head, so report F_j is column F_{N-1-j}."""
    return ["T", *(f"F{j}" for j in range(1, n_robots - 1)), "H"]


def evaluate_chain(pred: Predictor, world: np.ndarray) -> dict:
    """Errors (cm) of every robot the Tail cannot see: per robot, per step, and their mean."""
    est = predict_chain(pred, world)
    n_robots, hist = world.shape[2], pred.history
    names = report_names(n_robots)
    file_names = robot_names(n_robots)[::-1]
    unseen = unseen_errors(est[:, hist:, ::-1, :2], world[:, hist:, ::-1, :2])  # (B, steps, robots)
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
        "first_step": hist,
        "step_s": STEP_S,
        "n_instances": int(world.shape[0]),
        "n_robots": n_robots,
        "csv_robot": {names[j]: file_names[j] for j in range(2, n_robots)},
    }
