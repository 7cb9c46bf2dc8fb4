"""Data-collection policies of the Tail (seed §3.3–3.5.1): passive, or random perturbations.

`random` perturbs the Tail's destination with N(0, sigma^2 I), sigma a fraction of the robot's
size, drawing a new perturbation every log step, and alternates random and passive modes every
`alternate` steps so the Tail never loses its team.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np
import pyarrow as pa

from macrostate_mj.chain.motion import draw_tail_offsets
from macrostate_mj.chain.sim import ChainSim, Tracker
from macrostate_mj.core.errors import UserError

POLICIES = ("passive", "random")


class PolicyHook(Protocol):
    """Called once per log step to set `sim.tail_offset`; `records()` is what it decided, per
    step, for the collection to keep beside the poses (None: nothing worth keeping)."""

    def __call__(self, sim: ChainSim) -> None: ...

    def records(self) -> pa.Table | None: ...


class PolicySpec(Protocol):
    """A picklable policy configuration that an episode task carries to its worker, where
    `build` makes the hook (the SR phase's lives in `collectors.srs_policy`); `tracker` is the
    episode's camera chain, for a policy that acts on tracked poses."""

    name: str

    def build(self, rng: np.random.Generator, tracker: Tracker | None = None) -> PolicyHook: ...


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

    def build(self, rng: np.random.Generator, tracker: Tracker | None = None) -> TailPolicy:
        return TailPolicy(self, rng)


class TailPolicy:
    """A periodic hook, one call per log step, setting the simulation's Tail offset."""

    def __init__(self, cfg: PolicyConfig, rng: np.random.Generator):
        self.cfg = cfg
        self.rng = rng
        self.step = 0

    def __call__(self, sim: ChainSim) -> None:
        random_mode = self.cfg.name == "random" and (self.step // self.cfg.alternate) % 2 == 0
        if random_mode:
            sim.tail_offset = draw_tail_offsets(self.rng, self.cfg.sigma)
        else:
            sim.tail_offset = np.zeros(2)
        self.step += 1

    def records(self) -> pa.Table | None:
        return None
