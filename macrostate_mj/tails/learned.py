"""A learned Tail: a trained policy's deterministic action behind the spacing shield.

The spacing shield (`shield`): when the Tail sees its neighbour farther than a limit, its action
becomes passive (offset 0: the chain's own rule closes the gap) until the gap is back under it.
It uses only what the Tail observes, and keeps a policy from ending an episode with a chain
break (`chain.sim.BREAK_SPACINGS`). `ppo` trains the policy through the same shield.
"""

from __future__ import annotations

from typing import Any

import numpy as np


def shield(obs: dict[str, np.ndarray], action: np.ndarray, limit_m: float | None
           ) -> np.ndarray:
    """`action`, or offset 0 (passive) when the Tail's neighbour is farther than `limit_m`
    (None: no shield)."""
    if limit_m is None:
        return action
    gap = float(np.linalg.norm(obs["neighbour"][-1, :2] - obs["tail"][-1, :2]))
    return np.zeros_like(action) if gap > limit_m else action


def shield_limit(env: Any, spacings: float | None) -> float | None:
    """The shield's gap limit (m): `spacings` × the env's chain spacing; None: no shield."""
    return None if spacings is None else spacings * env.unwrapped.task.sim.cfg.spacing


class Learned:
    """A stable-baselines3 policy, deterministic at evaluation, behind its spacing shield."""

    def __init__(self, model: Any, limit_m: float | None = None):
        self.model, self.limit_m = model, limit_m

    def act(self, obs: dict, info: dict) -> np.ndarray:
        return shield(obs, self.model.predict(obs, deterministic=True)[0], self.limit_m)
