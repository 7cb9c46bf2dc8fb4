"""A Tail in a collection's episodes (seed §3.3–3.5.1): a hook the simulation calls once per
log step, which sets `ChainSim.tail_offset` to what the Tail chooses: `passive`, or `random`
(Rand-Only, `scripted.RandOnly`: N(0, sigma^2 I), sigma a fraction of the robot's size, each
log step in random mode, alternating with passive mode every `alternate` steps). An episode task
carries a picklable `PolicySpec` to its worker, where `build` makes the hook (the SR phase's is
`srs.SRSConfig`'s).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np
import pyarrow as pa

from macrostate_mj.chain.sim import ChainSim, Tracker
from macrostate_mj.core.errors import UserError
from macrostate_mj.core.registry import Registry
from macrostate_mj.tails import Tail
from macrostate_mj.tails.scripted import Passive, RandOnly

# The collection policies by name: the Tail each makes for an episode (`PolicyConfig.build`).
POLICIES: Registry[Callable[[np.random.Generator, PolicyConfig], Tail]] = Registry("policy")


@POLICIES.register("passive")
def _passive(rng: np.random.Generator, cfg: PolicyConfig) -> Tail:
    return Passive()


@POLICIES.register("random")
def _random(rng: np.random.Generator, cfg: PolicyConfig) -> Tail:
    return RandOnly(rng, cfg.sigma, None, cfg.alternate)


class PolicyHook(Protocol):
    """Called once per log step to set `sim.tail_offset`; `records()` is what it decided, per
    step, for the collection to keep beside the poses (None: nothing worth keeping)."""

    def __call__(self, sim: ChainSim) -> None: ...

    def records(self) -> pa.Table | None: ...


class PolicySpec(Protocol):
    """A picklable policy configuration that an episode task carries to its worker, where
    `build` makes the hook (the SR phase's lives in `tails.srs`); `tracker` is the episode's
    camera chain, for a policy that acts on tracked poses."""

    name: str

    def build(self, rng: np.random.Generator, tracker: Tracker | None = None) -> PolicyHook: ...


@dataclass(frozen=True)
class PolicyConfig:
    name: str = "passive"
    sigma: float = 0.75        # fraction of the robot size (75 % was best in the seed)
    alternate: int = 6         # steps per random / passive mode

    def __post_init__(self) -> None:
        POLICIES[self.name]         # an unknown name is refused, naming the choices
        if self.sigma < 0:
            raise UserError(f"--sigma must be non-negative, got {self.sigma}")

    def build(self, rng: np.random.Generator, tracker: Tracker | None = None) -> TailPolicy:
        return TailPolicy(POLICIES[self.name](rng, self))


class TailPolicy:
    """A periodic hook, one call per log step, setting the simulation's Tail offset to what
    its `Tail` chooses (a collection's Tails draw without looking: `obs` is empty)."""

    def __init__(self, tail: Tail):
        self.tail = tail

    def __call__(self, sim: ChainSim) -> None:
        sim.tail_offset = self.tail.act({}, {"t": sim.time})

    def records(self) -> pa.Table | None:
        return None
