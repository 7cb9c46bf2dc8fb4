"""Scripted Tails: Passive, Rand-Only, a uniform random offset and a fixed offset in the
chain's frame."""

from __future__ import annotations

import numpy as np

from macrostate_mj.chain.motion import draw_tail_offsets


class Passive:
    """Offset 0: the chain's own rule (the text's Passive Tail, the team that cannot cage)."""

    detected_at: float | None = None
    head_estimate: np.ndarray | None = None

    def act(self, obs: dict, info: dict) -> np.ndarray:
        return np.zeros(2, np.float32)


class RandOnly:
    """Rand-Only (§3.3): N(0, (σ · robot size)² I) each step in random mode, alternating with
    passive mode every `alternate` steps so the Tail never loses its team; in an environment
    clipped to the action bounds (`bound`; σ · size is well inside them) as float32, in a
    collection (`bound` None) as drawn."""

    def __init__(self, rng: np.random.Generator, sigma: float, bound: float | None = None,
                 alternate: int = 6):
        self.rng, self.sigma, self.bound, self.alternate = rng, sigma, bound, alternate
        self.step = 0

    def act(self, obs: dict, info: dict) -> np.ndarray:
        random_mode = (self.step // self.alternate) % 2 == 0
        self.step += 1
        if self.bound is None:
            return draw_tail_offsets(self.rng, self.sigma) if random_mode else np.zeros(2)
        if not random_mode:
            return np.zeros(2, np.float32)
        return np.clip(draw_tail_offsets(self.rng, self.sigma), -self.bound,
                       self.bound).astype(np.float32)


class Uniform:
    """A new uniform offset within `bound` (the action space's high) every `every` steps."""

    detected_at: float | None = None
    head_estimate: np.ndarray | None = None

    def __init__(self, rng: np.random.Generator, bound: np.ndarray, every: int):
        self.rng, self.bound, self.every = rng, bound, every
        self._action = np.zeros(2, np.float32)
        self._steps = 0

    def act(self, obs: dict, info: dict) -> np.ndarray:
        if self._steps % self.every == 0:
            self._action = self.rng.uniform(-1, 1, 2).astype(np.float32) * self.bound
        self._steps += 1
        return self._action


class ChainOffset:
    """The offset `along` (m, toward the neighbour) and `left` (m, to its left) in the frame of
    the Tail -> neighbour direction at the latest observation: it holds the neighbour at one
    bearing and distance from the Tail, whichever way the Head leads."""

    def __init__(self, along: float, left: float):
        self.along, self.left = along, left

    def act(self, obs: dict, info: dict) -> np.ndarray:
        d = obs["neighbour"][-1, :2] - obs["tail"][-1, :2]
        u = d / max(float(np.linalg.norm(d)), 1e-9)
        return (self.along * u + self.left * np.array([-u[1], u[0]])).astype(np.float32)
