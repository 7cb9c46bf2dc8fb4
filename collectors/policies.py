"""Data-collection policies of the Tail (seed §3.3–3.5.1): passive, or random perturbations.

`random` perturbs the Tail's destination with N(0, sigma^2 I), sigma a fraction of the robot's
size, drawing a new perturbation every log step, and alternates random and passive modes every
`alternate` steps so the Tail never loses its team.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from macrostate_mj.chain.sim import ChainSim
from macrostate_mj.core.errors import UserError

ROBOT_SIZE_M = 0.11        # Thymio II size used by the seed to scale sigma (§3.3)
POLICIES = ("passive", "random")


@dataclass(frozen=True)
class PolicyConfig:
    name: str = "passive"
    sigma: float = 0.75        # fraction of the robot size (75 % was best in the seed)
    alternate: int = 6         # steps per random / passive mode

    def __post_init__(self) -> None:
        if self.name not in POLICIES:
            raise UserError(f"unknown policy {self.name!r}; choose {' or '.join(POLICIES)}")
        if self.sigma < 0:
            raise UserError(f"--sigma must be non-negative, got {self.sigma}")


class TailPolicy:
    """A periodic hook, one call per log step, setting the simulation's Tail offset."""

    def __init__(self, cfg: PolicyConfig, rng: np.random.Generator):
        self.cfg = cfg
        self.rng = rng
        self.step = 0

    def __call__(self, sim: ChainSim) -> None:
        random_mode = self.cfg.name == "random" and (self.step // self.cfg.alternate) % 2 == 0
        if random_mode:
            sim.tail_offset = self.rng.normal(0.0, self.cfg.sigma * ROBOT_SIZE_M, size=2)
        else:
            sim.tail_offset = np.zeros(2)
        self.step += 1
