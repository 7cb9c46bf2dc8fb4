"""Synthetic inputs shared by several test modules (imported by name: conftest puts tests/ on the
path)."""

from pathlib import Path

import cv2
import mujoco
import numpy as np


def make_layout(root: Path, stable: int = 10, unstable=(1333, 1999, 5000), subframes: int = 2,
                seed: int = 0) -> Path:
    """A tiny dataset: stable samples barely move, unstable ones move 4 px; splits 8/2."""
    rng = np.random.default_rng(seed)
    for label, ids, shift in (("Stable", range(stable), 0.0), ("Unstable", unstable, 4.0)):
        (root / label).mkdir(parents=True)
        for i in ids:
            for k in range(subframes):
                for axis in ("x", "y"):
                    val = 127.5 + (shift + rng.normal(0, 0.3, (64, 64))) * 255 / 40
                    img = np.clip(np.rint(val), 0, 255).astype(np.uint8)
                    cv2.imwrite(str(root / label / f"flow_{axis}_{i:05d}-{k}.jpg"), img)
                cv2.imwrite(str(root / label / f"img_{i:05d}-{k}.jpg"),
                            rng.integers(0, 255, (64, 64, 3), dtype=np.uint8))
    for s in (1, 2, 3):
        (root / f"split{s}").mkdir()
        order = np.random.default_rng(s).permutation(stable)
        cut = int(0.8 * stable)
        for part, ids in (("train", order[:cut]), ("test", order[cut:])):
            (root / f"split{s}" / f"{part}.csv").write_text(
                "".join(f"Stable/{i:05d}\n" for i in ids))
    return root


def drive(sim, left: float, right: float, seconds: float) -> np.ndarray:
    """Hold wheel speeds on robot 0 and return its (x, y, theta) every physics step."""
    w = sim.world
    sim.data.ctrl[w.ctrl_left[0]] = left
    sim.data.ctrl[w.ctrl_right[0]] = right
    out = []
    for _ in range(int(round(seconds / sim.model.opt.timestep))):
        mujoco.mj_step(sim.model, sim.data)
        out.append(sim.poses[0])
    return np.array(out)
