"""The Tail's controllers, one room: every way the chain's Tail can choose where to go.

A Tail acts once per step through one protocol, `Tail.act(obs, info) -> offset`: `obs` is what
the Tail observes (its and its neighbour's recent poses, what its sensor sees; empty in a
collection, whose Tails draw without looking), `info` the step's information (`t`, the time in
s, always; what the team shares, where it does), and the offset (2,) m moves the destination the
chain's rule gives the Tail, the action of every Tail environment and what a collection sets as
`ChainSim.tail_offset`. A Tail that reads the whole team's true poses (SRS's, privileged) is
given the simulation when it is made.

- `scripted`: Passive, Rand-Only, a uniform random offset, a fixed offset in the chain's frame;
- `caging`: the scripted caging Tail, the cooperating pair, and where their Head position comes
  from (the truth, or a live estimator);
- `srs`: SRS's Tail (§3.3.1) and the SR phase that collects with it;
- `learned`: a trained policy behind the spacing shield, and `ppo`, the loop that trains it;
- `collection`: the hooks that run a Tail inside a collection's episodes.

The room sits below `collectors`, `estimators` and `env` and imports none of them: what a Tail
needs from them (novelty models, an online estimator, a policy network, an environment) is
passed in.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np


class Tail(Protocol):
    """One Tail for one episode (see the module docstring)."""

    def act(self, obs: dict, info: dict) -> np.ndarray: ...
