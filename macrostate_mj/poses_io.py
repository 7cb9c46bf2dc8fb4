"""`poses.parquet`: the long-format pose log, one row per robot per logged step.

Columns: t (s), step (log index), robot (H, F1.., T), x, y (m, world frame, origin at the arena
centre, x along the long side), theta (rad, CCW from +x, in (-pi, pi]), waypoint_x/y (the Head's
current target, NaN without one) and, when tracking ran, x_trk, y_trk, theta_trk, detected.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from macrostate_mj.io import atomic_path
from macrostate_mj.motion import wrap_angle


def poses_table(names: list[str], times: np.ndarray, poses: np.ndarray, waypoints: np.ndarray,
                tracked: np.ndarray | None = None, detected: np.ndarray | None = None
                ) -> pa.Table:
    """Arrays (T,), (T, n, 3), (T, 2) [, (T, n, 3), (T, n)] -> long-format table."""
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
    if tracked is not None:
        cols |= {"x_trk": tracked[:, :, 0].ravel(), "y_trk": tracked[:, :, 1].ravel(),
                 "theta_trk": tracked[:, :, 2].ravel(),
                 "detected": np.asarray(detected, bool).ravel()}
    return pa.table(cols)


def write_poses(path: str | Path, table: pa.Table) -> None:
    with atomic_path(path) as tmp:
        pq.write_table(table, tmp, compression="zstd")


def read_pose_arrays(path: str | Path) -> tuple[list[str], np.ndarray, np.ndarray]:
    """Back to (names, times (T,), poses (T, n, 3)) from a `poses.parquet`."""
    table = pq.read_table(path, columns=["t", "robot", "x", "y", "theta"]).to_pydict()
    robots = table["robot"]
    n = robots.index(robots[0], 1) if robots.count(robots[0]) > 1 else len(robots)
    xyz = np.column_stack([table["x"], table["y"], table["theta"]]).reshape(-1, n, 3)
    return robots[:n], np.asarray(table["t"][::n]), xyz
