"""The test cases of Fig 2.2 (§2.5.3): which chain, which Head path, which knowledge.

Head paths, both driven by the presets the networks were trained on:
  straight  preset 0 (straight ahead) throughout;
  curve     straight, then the tight left preset (ω = 0.2 rad/s, radius 0.15 m) from 22 % to
            51.5 % of the run (a U-turn at 1,600 steps), then straight again, so the error can
            peak in the turn and recover afterwards as in Fig 2.2b-c.
The 1,600-step curve fits the 1.2 × 0.7 arena; the straight run does not (collectors.robotarium).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from collectors.robotarium import fit_start, run_chain, twists_of
from macrostate_mj.chain.scenario import ScenarioConfig
from macrostate_mj.chain.world import build_world

TURN_PRESET = 3                   # (0.03 m/s, +0.2 rad/s)
TURN_SPAN = (0.22, 0.515)         # fractions of the run spent turning


@dataclass(frozen=True)
class Case:
    key: str
    title: str
    n_robots: int
    path: str                     # "straight" | "curve"
    comm: bool = False            # true poses every `comm_every` steps (§2.5.3.2)
    noisy: bool = False           # N(0, σ²) on everything fed to the networks (§2.5.3.3)


CASES: tuple[Case, ...] = (
    Case("a", "straight, 6 robots", 6, "straight"),
    Case("b", "curve, 5 robots", 5, "curve"),
    Case("c", "curve, 6 robots", 6, "curve"),
    Case("d", "curve, 6 robots, true poses every {comm} steps", 6, "curve", comm=True),
    Case("e", "(b) with noisy inputs", 5, "curve", noisy=True),
    Case("f", "(d) with noisy inputs", 6, "curve", comm=True, noisy=True),
)


def schedule(path: str, steps: int) -> tuple[tuple[int, int], ...]:
    """(start step, preset) pairs of a Head path."""
    if path == "straight":
        return ((0, 0),)
    a, b = (round(f * steps) for f in TURN_SPAN)
    return ((0, 0), (a, TURN_PRESET), (b, 0))


def case_run(cfg: ScenarioConfig, n: int, path: str, steps: int) -> tuple[np.ndarray, str]:
    """Clean poses (steps, n, 3), Head first, of one test chain at the scenario's k_t, and the
    floor it ran on ("arena", or "open" when the run cannot fit between the walls)."""
    sched = schedule(path, steps)
    start, room = fit_start(cfg, n, twists_of(sched, steps))
    walls = room >= 0
    world = build_world(cfg if walls else cfg.with_overrides(walls=None), n, start)
    return run_chain(world, start, steps, cfg.k_t, sched, walls=walls), \
        "arena" if walls else "open"


def tail_view(poses: np.ndarray, sync: np.ndarray, sigma: float, rng: np.random.Generator
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """What the Tail is given from a clean run (Head first): sensed (S, 2, 2) own and Follower 1
    positions, synced (len(sync), N, 3) poses; both with N(0, σ²) when σ > 0. Also the
    clean truth, Tail first."""
    truth = poses[:, ::-1].astype(np.float64)
    sensed = truth[:, :2, :2].copy()
    synced = truth[sync].copy()
    if sigma > 0:
        sensed += rng.normal(0.0, sigma, sensed.shape)
        synced += rng.normal(0.0, sigma, synced.shape)
    return sensed, synced, truth


def case_runs(cfg: ScenarioConfig, steps: int,
              progress: Callable[[int, int], None] | None = None
              ) -> dict[tuple[int, str], tuple[np.ndarray, str]]:
    """Every test chain the cases need, once each, keyed (robots, path) in sorted order:
    `case_run`'s poses and floor (cases sharing a chain share its run)."""
    needed = sorted({(c.n_robots, c.path) for c in CASES})
    runs = {}
    for i, (n, path) in enumerate(needed):
        runs[(n, path)] = case_run(cfg, n, path, steps)
        if progress:
            progress(i + 1, len(needed))
    return runs
