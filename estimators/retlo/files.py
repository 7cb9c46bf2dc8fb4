"""ThymioLoc files in the package's unit: camera pixels and degrees become metres and radians
here, where files are read (`read_world`), and pixels again only for drawing and writing
(`world_to_pixels`). Pure numpy, so that callers need not import torch to read data."""

from __future__ import annotations

import os

import numpy as np

from estimators.retlo import CM_PER_M
from macrostate_mj.formats.thymioloc import DEFAULT_PX_PER_CM, from_world, read_csv, to_world


def pixels_to_world(px: np.ndarray, px_per_cm: float = DEFAULT_PX_PER_CM) -> np.ndarray:
    """ThymioLoc pixels/degrees (..., 3) → metres (x right, y up) and radians."""
    world = to_world(px, px_per_cm)
    world[..., :2] /= CM_PER_M
    return world


def world_to_pixels(world: np.ndarray, px_per_cm: float = DEFAULT_PX_PER_CM) -> np.ndarray:
    """Inverse of `pixels_to_world`: metres and radians → ThymioLoc pixels and degrees."""
    cm = np.array(world, np.float64)
    cm[..., :2] *= CM_PER_M
    return from_world(cm, px_per_cm)


def read_world(path: str | os.PathLike, px_per_cm: float = DEFAULT_PX_PER_CM) -> np.ndarray:
    """A ThymioLoc CSV as chains (B, S, N, 3) in metres and radians, file order (Head first)."""
    return pixels_to_world(read_csv(path).poses, px_per_cm)
