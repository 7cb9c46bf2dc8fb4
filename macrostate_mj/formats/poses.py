"""`poses.parquet`: the long-format pose log, one row per robot per logged step.

Columns: t (s), step (log index), robot (H, F1.., T), x, y (m, world frame, origin at the arena
centre, x along the long side), theta (rad, CCW from +x, in (-pi, pi]), waypoint_x/y (the Head's
current target, NaN without one) and, when tracking ran, x_trk, y_trk, theta_trk (the latest
detection, same units, with the scenario's `marker_jitter` added), t_trk (when it was made),
x_truth_trk, y_truth_trk, theta_truth_trk (the true pose at t_trk) and detected (seen in the
latest frame). So x_trk - x_truth_trk is the tracker's error plus the drawn jitter (in `lab`,
median about 3.5 mm, of which the tracker's own is 1-2 mm), while x_trk - x adds the motion
since t_trk. The tracker's own error, before the jitter and over every processed frame, is the run
manifest's `tracking.health` (`vision.health`), judged against the scenario's `[tracking]`
limits. Each field's unit is in the
schema metadata (`unit`), the frame convention in the table's (`frame`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from macrostate_mj.core.angles import wrap_angle
from macrostate_mj.core.io import atomic_path

UNITS = {"t": "s", "step": "log step", "robot": "name", "x": "m", "y": "m", "theta": "rad",
         "waypoint_x": "m", "waypoint_y": "m", "x_trk": "m", "y_trk": "m", "theta_trk": "rad",
         "t_trk": "s", "x_truth_trk": "m", "y_truth_trk": "m", "theta_truth_trk": "rad",
         "detected": "bool"}
FRAME = ("world frame: origin at the arena centre, x along the long side, y to its left, "
         "theta counter-clockwise from +x in (-pi, pi]; robots H, F1.., T from the Head")


def poses_table(names: list[str], times: np.ndarray, poses: np.ndarray, waypoints: np.ndarray,
                tracking: dict[str, np.ndarray] | None = None) -> pa.Table:
    """Arrays (T,), (T, n, 3), (T, 2) [+ `PoseLog.tracked_arrays()`] -> long-format table."""
    n_t, n = poses.shape[:2]
    cols = {
        "t": np.repeat(np.asarray(times, float), n),
        "step": np.repeat(np.arange(n_t, dtype=np.int64), n),
        "robot": np.tile(np.array(names, dtype=object), n_t),
        "x": poses[:, :, 0].ravel(),
        "y": poses[:, :, 1].ravel(),
        "theta": wrap_angle(poses[:, :, 2].ravel()),
        "waypoint_x": np.repeat(waypoints[:, 0], n),
        "waypoint_y": np.repeat(waypoints[:, 1], n),
    }
    if tracking is not None:
        trk = tracking["tracked"]
        truth = tracking["tracked_truth"]
        cols |= {"x_trk": trk[:, :, 0].ravel(), "y_trk": trk[:, :, 1].ravel(),
                 "theta_trk": trk[:, :, 2].ravel(), "t_trk": tracking["tracked_time"].ravel(),
                 "x_truth_trk": truth[:, :, 0].ravel(), "y_truth_trk": truth[:, :, 1].ravel(),
                 "theta_truth_trk": wrap_angle(truth[:, :, 2].ravel()),
                 "detected": np.asarray(tracking["detected"], bool).ravel()}
    table = pa.table(cols)
    fields = [f.with_metadata({"unit": UNITS[f.name]}) for f in table.schema]
    return table.cast(pa.schema(fields, metadata={"frame": FRAME}))


def write_poses(path: str | Path, table: pa.Table) -> None:
    with atomic_path(path) as tmp:
        pq.write_table(table, tmp, compression="zstd")


def table_arrays(table: pa.Table) -> dict[str, np.ndarray | list[str]]:
    """Back to arrays from one run's long table: names, t (T,), poses (T, n, 3) and, when
    tracked, tracked (T, n, 3) and detected (T, n)."""
    robots = table.column("robot").to_pylist()
    n = robots.index(robots[0], 1) if robots.count(robots[0]) > 1 else len(robots)

    def stack(*cols: str) -> np.ndarray:
        return np.column_stack([table.column(c).to_numpy() for c in cols]).reshape(-1, n, len(cols))

    out: dict[str, np.ndarray | list[str]] = {
        "names": robots[:n], "t": table.column("t").to_numpy()[::n],
        "poses": stack("x", "y", "theta")}
    if "x_trk" in table.column_names:
        out["tracked"] = stack("x_trk", "y_trk", "theta_trk")
        out["detected"] = stack("detected")[..., 0].astype(bool)
    return out
