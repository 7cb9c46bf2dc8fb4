"""Distributions of a chain's motion in ThymioLoc files, and their distance between two files.

Means hide what sim-to-real needs to match (a simulated Head at the real mean speed may still
stop and go where the real one glides), so `stats --compare` compares distributions: per robot
and pooled, each feature's values in both files and the two-sample Kolmogorov-Smirnov distance
between them (scipy). Features, from poses (instances, steps, robots, 3) in px and degrees:

- spacing_cm: distance between neighbours (per pair; pooled over pairs);
- speed_cm_s, turn_deg_s (signed), heading_change_deg (signed, per step), accel_cm_s2;
- wait_share: per instance, the share of steps a robot moves under WAIT_CM_S;
- jitter_cm: the residual of each position to its Savitzky-Golay smoothed track (5 steps,
  quadratic), i.e. the tracker's high-frequency noise plus true jerks;
- speed_acf_lag{k}, turn_acf_lag{k}: per instance, the lag-k autocorrelation (k = 1..10).
"""

from __future__ import annotations

import numpy as np

from macrostate_mj.core.errors import UserError
from macrostate_mj.formats.thymioloc import STEP_S, robot_names

WAIT_CM_S = 1.0
LAGS = tuple(range(1, 11))
SMOOTH_STEPS = 5


def _acf(x: np.ndarray, lag: int) -> np.ndarray:
    """Lag-`lag` autocorrelation of each row of x (instances, steps); NaN for a still row."""
    x = x - x.mean(axis=1, keepdims=True)
    den = (x * x).sum(axis=1)
    num = (x[:, lag:] * x[:, :-lag]).sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 0, num / den, np.nan)


def features(poses: np.ndarray, px_per_cm: float, step_s: float = STEP_S
             ) -> dict[str, dict[str, np.ndarray]]:
    """{feature: {robot or pair name, and "pooled": values}} of one file's poses."""
    from scipy.signal import savgol_filter

    poses = np.asarray(poses, np.float64)
    n_steps, n_robots = poses.shape[1], poses.shape[2]
    if n_steps <= max(LAGS) + 2 or n_steps < SMOOTH_STEPS:
        raise UserError(f"instances of {n_steps} steps are too short for lag-{max(LAGS)} "
                        "autocorrelations; use files of ThymioLoc instances (26 steps)")
    names = robot_names(n_robots)
    xy = poses[..., :2] / px_per_cm
    step = np.diff(xy, axis=1)
    speed = np.linalg.norm(step, axis=-1) / step_s                     # (I, S-1, R)
    dhead = (np.diff(poses[..., 2], axis=1) + 180.0) % 360.0 - 180.0   # (I, S-1, R)
    accel = np.diff(speed, axis=1) / step_s
    smooth = savgol_filter(xy, SMOOTH_STEPS, 2, axis=1)
    jitter = np.linalg.norm(xy - smooth, axis=-1)
    per_robot = {"speed_cm_s": speed, "turn_deg_s": dhead / step_s, "heading_change_deg": dhead,
                 "accel_cm_s2": accel, "jitter_cm": jitter,
                 "wait_share": (speed < WAIT_CM_S).mean(axis=1)[:, None, :]}
    for lag in LAGS:
        per_robot[f"speed_acf_lag{lag}"] = np.stack(
            [_acf(speed[..., r], lag) for r in range(n_robots)], -1)[:, None, :]
        per_robot[f"turn_acf_lag{lag}"] = np.stack(
            [_acf(dhead[..., r], lag) for r in range(n_robots)], -1)[:, None, :]
    out: dict[str, dict[str, np.ndarray]] = {}
    gaps = np.linalg.norm(np.diff(xy, axis=2), axis=-1)               # (I, S, R-1)
    out["spacing_cm"] = {f"{a}-{b}": gaps[..., i].ravel()
                         for i, (a, b) in enumerate(zip(names, names[1:], strict=False))}
    out["spacing_cm"]["pooled"] = gaps.ravel()
    for name, values in per_robot.items():
        out[name] = {r: _finite(values[..., i]) for i, r in enumerate(names)}
        out[name]["pooled"] = _finite(values)
    return out


def _finite(v: np.ndarray) -> np.ndarray:
    v = np.asarray(v, np.float64).ravel()
    return v[np.isfinite(v)]


def compare(a: dict, b: dict) -> list[dict]:
    """One row per (feature, robot): both medians and means, the KS distance and its p-value."""
    from scipy.stats import ks_2samp

    rows = []
    for feature, per in a.items():
        for who, va in per.items():
            vb = b[feature].get(who)
            if vb is None or len(va) == 0 or len(vb) == 0:
                continue
            ks = ks_2samp(va, vb)
            rows.append({"feature": feature, "robot": who, "n": [int(len(va)), int(len(vb))],
                         "mean": [float(va.mean()), float(vb.mean())],
                         "median": [float(np.median(va)), float(np.median(vb))],
                         "ks": float(ks.statistic), "p": float(ks.pvalue)})
    return rows


def family(feature: str) -> str:
    """The statistic a compared row belongs to: each autocorrelation's ten lags are one."""
    return feature.split("_lag")[0] if "_acf_lag" in feature else feature


def rank(rows: list[dict]) -> list[dict]:
    """The statistics of `compare`'s rows, farthest apart first: per robot (or pair) its KS
    distance (an autocorrelation's lags averaged, so that ten lags weigh as one statistic),
    their sum and the worst; the pooled rows are left out (robots differ: pooling hides it)."""
    per: dict[str, dict[str, list[float]]] = {}
    for r in rows:
        if r["robot"] != "pooled":
            per.setdefault(family(r["feature"]), {}).setdefault(r["robot"], []).append(r["ks"])
    ranked = [{"statistic": name,
               "ks": {who: float(np.mean(v)) for who, v in robots.items()}}
              for name, robots in per.items()]
    for r in ranked:
        r["sum"] = float(sum(r["ks"].values()))
        r["worst"] = max(r["ks"], key=r["ks"].get)
    return sorted(ranked, key=lambda r: (-r["ks"][r["worst"]], r["statistic"]))


def check_comparable(shape_a: tuple[int, ...], shape_b: tuple[int, ...], names: tuple[str, str]
                     ) -> None:
    """Two files compare robot by robot only with the same team size and instance length."""
    if shape_a[2] != shape_b[2]:
        raise UserError(f"{names[0]} has {shape_a[2]} robots and {names[1]} {shape_b[2]}; "
                        "compare files of the same team size")
    if shape_a[1] != shape_b[1]:
        raise UserError(f"{names[0]} has {shape_a[1]}-step instances and {names[1]} "
                        f"{shape_b[1]}; compare files of the same layout")
