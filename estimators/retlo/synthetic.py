"""Synthetic chains with a known law, for tests and for benchmarks on a machine without data.

A Head on a unicycle path with a randomly drifting turn rate; every robot behind it steers
straight toward its leader to restore the spacing (a proportional rule in the spirit of §2.3).
Not a substitute for `collect` data: no physics, no camera, no tracker.
"""

from __future__ import annotations

import numpy as np


def synthetic_chains(n_inst: int, n_robots: int, seed: int, n_steps: int = 26,
                     spacing: float = 0.31, head_speed: float = 0.08) -> np.ndarray:
    """(n_inst, n_steps, n_robots, 3) world poses (m, rad) in file order (Head first), 2 Hz."""
    rng = np.random.default_rng(seed)
    sub, dt = 10, 0.05
    head0 = rng.uniform(-np.pi, np.pi, n_inst)
    back = np.stack([np.cos(head0), np.sin(head0)], -1)
    pos = -spacing * np.arange(n_robots)[None, :, None] * back[:, None, :]
    theta = np.repeat(head0[:, None], n_robots, axis=1)
    omega = rng.uniform(-0.4, 0.4, n_inst)
    out = np.zeros((n_inst, n_steps, n_robots, 3))
    for step in range(n_steps):
        out[:, step, :, :2], out[:, step, :, 2] = pos, theta
        omega = np.clip(omega + rng.normal(0, 0.15, n_inst), -0.6, 0.6)
        for _ in range(sub):
            theta[:, 0] += omega * dt
            pos[:, 0] += head_speed * dt * np.stack([np.cos(theta[:, 0]), np.sin(theta[:, 0])], -1)
            for r in range(1, n_robots):
                gap = pos[:, r - 1] - pos[:, r]
                dist = np.linalg.norm(gap, axis=-1)
                speed = np.clip(0.6 * (dist - spacing), 0.0, 0.12)
                pos[:, r] += (speed * dt / dist)[:, None] * gap
                moving = speed > 0.001
                theta[:, r] = np.where(moving, np.arctan2(gap[:, 1], gap[:, 0]), theta[:, r])
    out[..., 2] = (out[..., 2] + np.pi) % (2 * np.pi) - np.pi
    return out
