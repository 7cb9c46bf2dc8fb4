"""Fig 2.9's qualitative claims, measured: where on a curve the estimates lie, and which robot
of the chain carries the instant's largest error.

§2.6.3 reads its sample frames as "predictions tend to be biased more toward the inside of the
curve the team is moving on" and "the maximum position error is often at intermediate
Follower robots and not at the most distant Head". Both become numbers here, over every
estimated robot and step:

- **inside bias**: the estimate's error across the robot's own path (positive to the left of its
  direction of travel), signed by the way the path turns there (positive turning left), so a
  positive mean is a bias toward the inside of the curve. Only steps where the true path turns
  by at least `MIN_TURN` a step and moves at least `MIN_MOVE` count: on a straight stretch, or
  for a robot waiting in place, there is no inside.
- **largest error**: at each instant where every unseen robot has an estimate, which one errs
  most; the share of instants each robot is that one.

Pure numpy, on `predict_chain`'s layout (file order H, F1.., T; NaN where nothing is
estimated); names follow the reports (Followers counted from the Tail).
"""

from __future__ import annotations

import numpy as np

from estimators.retlo.report import report_names

CM_PER_M = 100.0
MIN_TURN = 0.05   # rad a log step (0.5 s): about 6 °/s, a turn and not tracker noise
MIN_MOVE = 0.005  # m a log step: a robot that moves, not one waiting in place


def _turns(xy: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per step t (1..S-2) of paths (B, S, N, 2): the unit direction of travel (chord from t-1
    to t+1), the signed turn (rad, left positive) and whether the robot moves at both ends."""
    before, after = xy[:, 1:-1] - xy[:, :-2], xy[:, 2:] - xy[:, 1:-1]
    chord = xy[:, 2:] - xy[:, :-2]
    length = np.linalg.norm(chord, axis=-1, keepdims=True)
    direction = np.divide(chord, length, out=np.zeros_like(chord), where=length > 0)
    cross = before[..., 0] * after[..., 1] - before[..., 1] * after[..., 0]
    dot = (before * after).sum(-1)
    moving = ((np.linalg.norm(before, axis=-1) >= MIN_MOVE)
              & (np.linalg.norm(after, axis=-1) >= MIN_MOVE))
    return direction, np.arctan2(cross, dot), moving


def inside_bias(est: np.ndarray, world: np.ndarray) -> dict[str, dict[str, float | int | None]]:
    """Per unseen robot (report names) and pooled: the mean signed lateral error toward the
    inside of the curve (cm; positive = inside) and the number of curved steps it averages."""
    truth, guess = world[..., :2], est[..., :2]
    direction, turn, moving = _turns(truth)
    err = guess[:, 1:-1] - truth[:, 1:-1]
    lateral = direction[..., 0] * err[..., 1] - direction[..., 1] * err[..., 0]
    inward = CM_PER_M * lateral * np.sign(turn)
    curved = moving & (np.abs(turn) >= MIN_TURN) & np.isfinite(inward)
    names = report_names(world.shape[2])[::-1]          # file order: H first
    unseen = world.shape[2] - 2                          # the robots the Tail cannot see
    out = {names[n]: _mean(inward[..., n], curved[..., n]) for n in range(unseen)}
    out["pooled"] = _mean(inward[..., :unseen], curved[..., :unseen])
    return out


def _mean(values: np.ndarray, mask: np.ndarray) -> dict[str, float | int | None]:
    """The mean of the masked values (None when there are none) and how many there are."""
    n = int(mask.sum())
    return {"inside_cm": float(values[mask].mean()) if n else None, "steps": n}


def largest_error_share(est: np.ndarray, world: np.ndarray) -> dict[str, float]:
    """The share of instants at which each unseen robot (report names) errs most, over the
    instants where every unseen robot has an estimate."""
    unseen = world.shape[2] - 2
    err = np.linalg.norm(est[..., :unseen, :2] - world[..., :unseen, :2], axis=-1)
    complete = np.isfinite(err).all(axis=-1)
    worst = np.argmax(np.where(np.isfinite(err), err, -np.inf), axis=-1)[complete]
    names = report_names(world.shape[2])[::-1]
    return {names[n]: float(np.mean(worst == n)) for n in range(unseen)}
