"""ThymioLoc CSV: the published ReTLo data layout, read and written exactly, for any chain length.

One row per instance; columns time-major, then robot (H, F1, ..., F{n-2}, T, Followers counted
from the Head as in the published files), then x, y, o: `0_H_x,0_H_y,0_H_o,0_F1_x,...,25_T_o`.
Values are integers: camera pixels (x right, y down) and heading in degrees,
o = atan2(-dy, dx). Every file is validated in full before any value is used, so a bad row is
named by its line number instead of surfacing later as a shape error deep inside a model.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from macrostate_mj.core.errors import UserError
from macrostate_mj.core.io import atomic_path

STEP_S = 0.5  # the published log rate is 2 Hz
DEFAULT_PX_PER_CM = 3.0  # the real camera's scale (the published ThymioLoc set)
_INT = re.compile(r"-?\d+\Z")
_COLUMN = re.compile(r"(\d+)_(H|T|F\d+)_([xyo])\Z")


def robot_names(n_robots: int) -> list[str]:
    """Column robot names in file order: Head, Followers from the Head's side, Tail."""
    if n_robots < 2:
        raise UserError(f"a ThymioLoc chain needs at least 2 robots, got {n_robots}")
    return ["H", *(f"F{i}" for i in range(1, n_robots - 1)), "T"]


def header(n_robots: int, n_steps: int) -> list[str]:
    """The exact ThymioLoc column names for a chain of `n_robots` over `n_steps` steps."""
    names = robot_names(n_robots)
    return [f"{t}_{r}_{c}" for t in range(n_steps) for r in names for c in "xyo"]


@dataclass(frozen=True)
class ThymioLoc:
    """A ThymioLoc file as an array: poses[instance, step, robot, (x_px, y_px, o_deg)], int64."""

    poses: np.ndarray
    source: str = ""

    @property
    def n_instances(self) -> int:
        return int(self.poses.shape[0])

    @property
    def n_steps(self) -> int:
        return int(self.poses.shape[1])

    @property
    def n_robots(self) -> int:
        return int(self.poses.shape[2])

    @property
    def robots(self) -> list[str]:
        return robot_names(self.n_robots)


def _parse_header(path: Path, line: str) -> tuple[int, int]:
    """Infer (robots, steps) from a header and demand it be exactly ThymioLoc's for that size."""
    cols = line.split(",")
    parsed = [_COLUMN.match(c) for c in cols]
    if not cols or any(m is None for m in parsed) or len(cols) % 3:
        bad = next((c for c, m in zip(cols, parsed, strict=True) if m is None), cols[-1])
        raise UserError(f"{path}: line 1 is not a ThymioLoc header (column {bad!r}); expected "
                        "columns like 0_H_x,0_H_y,0_H_o,0_F1_x,...,25_T_o")
    n_steps = max(int(m.group(1)) for m in parsed if m) + 1
    n_robots = len(cols) // (3 * n_steps) if len(cols) % (3 * n_steps) == 0 else 0
    if n_robots < 2 or cols != header(n_robots, n_steps):
        raise UserError(f"{path}: line 1 is not a ThymioLoc header (columns out of order or "
                        "missing); expected time-major, then H, F1..., T, then x,y,o")
    return n_robots, n_steps


def read_csv(path: str | os.PathLike) -> ThymioLoc:
    """Read and fully validate a ThymioLoc CSV; any defect raises UserError naming file and line."""
    path = Path(path)
    try:
        text = path.read_text(encoding="ascii")
    except FileNotFoundError:
        raise UserError(f"{path}: no such file; pass an existing ThymioLoc CSV") from None
    except (UnicodeDecodeError, IsADirectoryError, PermissionError) as err:
        raise UserError(f"{path}: cannot read as a ThymioLoc CSV ({type(err).__name__})") from None
    lines = text.split("\n")
    if lines and lines[-1] == "":
        lines.pop()  # the terminating newline
    if not lines:
        raise UserError(f"{path}: empty file; a ThymioLoc CSV starts with its header line")
    n_robots, n_steps = _parse_header(path, lines[0].rstrip("\r"))
    n_fields = n_robots * n_steps * 3
    rows = []
    for lineno, raw in enumerate(lines[1:], start=2):
        fields = raw.rstrip("\r").split(",")
        if len(fields) != n_fields:
            raise UserError(f"{path}: line {lineno} has {len(fields)} fields, the header "
                            f"{n_fields}; fix or remove that row")
        bad = next((i for i, f in enumerate(fields) if not _INT.match(f)), None)
        if bad is not None:
            col = header(n_robots, n_steps)[bad]
            raise UserError(f"{path}: line {lineno}, column {col}: {fields[bad]!r} is not an "
                            "integer; ThymioLoc values are integer pixels and degrees")
        rows.append([int(f) for f in fields])
    if not rows:
        raise UserError(f"{path}: header only, no instances; a ThymioLoc CSV needs data rows")
    poses = np.asarray(rows, dtype=np.int64).reshape(len(rows), n_steps, n_robots, 3)
    return ThymioLoc(poses=poses, source=str(path))


def format_csv(poses: np.ndarray) -> str:
    """The CSV text of poses[instance, step, robot, 3], values rounded to the nearest integer."""
    poses = np.asarray(poses)
    if poses.ndim != 4 or poses.shape[3] != 3 or poses.shape[0] < 1:
        raise UserError("ThymioLoc poses must be (instances>=1, steps, robots, 3), "
                        f"got {poses.shape}")
    n_inst, n_steps, n_robots, _ = poses.shape
    values = np.rint(poses)
    values[..., 2] = wrap_degrees(values[..., 2])    # after rounding: -179.6 is 180, not -180
    values = values.astype(np.int64).reshape(n_inst, -1)
    lines = [",".join(header(n_robots, n_steps))]
    lines += [",".join(map(str, row)) for row in values.tolist()]
    return "\n".join(lines) + "\n"


def write_csv(path: str | os.PathLike, poses: np.ndarray) -> Path:
    """Write poses atomically in the exact published layout (LF line ends, final newline)."""
    path = Path(path)
    text = format_csv(poses)
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="ascii")
    return path


def to_world(poses: np.ndarray, px_per_cm: float) -> np.ndarray:
    """Pixels/degrees → (x cm right, y cm up, θ rad counter-clockwise): a right-handed frame.

    The camera's y axis points down, so y flips sign; o = atan2(-dy, dx) already measures the
    heading counter-clockwise in that flipped frame, so θ is simply o in radians.
    """
    poses = np.asarray(poses, dtype=np.float64)
    out = np.empty_like(poses)
    out[..., 0] = poses[..., 0] / px_per_cm
    out[..., 1] = -poses[..., 1] / px_per_cm
    out[..., 2] = np.deg2rad(poses[..., 2])
    return out


def from_world(world: np.ndarray, px_per_cm: float) -> np.ndarray:
    """Inverse of `to_world`: back to pixels (y down) and degrees in (-180, 180]."""
    world = np.asarray(world, dtype=np.float64)
    out = np.empty_like(world)
    out[..., 0] = world[..., 0] * px_per_cm
    out[..., 1] = -world[..., 1] * px_per_cm
    out[..., 2] = wrap_degrees(np.rad2deg(world[..., 2]))
    return out


def wrap_degrees(deg: np.ndarray) -> np.ndarray:
    """Wrap to (-180, 180], the real files' convention (180 appears in them, -180 never)."""
    return -((-np.asarray(deg, dtype=np.float64) + 180.0) % 360.0 - 180.0)


@dataclass(frozen=True)
class ChainStats:
    """What `macrostate-mj stats` prints: the figures that calibrate the `lab` scenario."""

    n_instances: int
    n_steps: int
    robots: list[str]
    spacing_cm: tuple[float, float, float, float]  # mean, std, 5th pct, 95th pct (all pairs)
    speed_cm_s: dict[str, float]  # mean per robot
    turn_deg_s: dict[str, float]  # mean |turn rate| per robot


def chain_stats(poses: np.ndarray, px_per_cm: float = DEFAULT_PX_PER_CM,
                step_s: float = STEP_S) -> ChainStats:
    """Neighbour spacing, per-robot speed and |turn rate| of poses[instance, step, robot, 3]."""
    poses = np.asarray(poses, dtype=np.float64)
    xy = poses[..., :2] / px_per_cm
    gaps = np.linalg.norm(np.diff(xy, axis=2), axis=-1).ravel()
    speed = np.linalg.norm(np.diff(xy, axis=1), axis=-1) / step_s  # (I, S-1, R)
    dturn = (np.diff(poses[..., 2], axis=1) + 180.0) % 360.0 - 180.0
    turn = np.abs(dturn) / step_s
    names = robot_names(poses.shape[2])
    return ChainStats(
        n_instances=int(poses.shape[0]), n_steps=int(poses.shape[1]), robots=names,
        spacing_cm=(float(gaps.mean()), float(gaps.std()),
                    float(np.percentile(gaps, 5)), float(np.percentile(gaps, 95))),
        speed_cm_s={r: float(speed[..., i].mean()) for i, r in enumerate(names)},
        turn_deg_s={r: float(turn[..., i].mean()) for i, r in enumerate(names)},
    )
