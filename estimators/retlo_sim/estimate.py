"""Chapter 2's module applied along a chain (§2.5.1.2) and its errors (§2.5.3), pure numpy.

The schedule, the robots' names and the error measure are `estimators.retlo.chain`'s, shared
with chapter 3; this module's own part is its one-step module and the sync steps.

Robots are indexed from the Tail here (0 = Tail, 1 = Follower 1, which the Tail senses, ...,
N-1 = Head); pose logs list them from the Head. Module k takes robot k as its (fictitious)
Tail, robot k+1 as its Follower and estimates robot k+2's position at t and robot k+1's heading
at t+1. Robot k+1's position at t+1 comes from module k-1 one step later, so a far robot's
estimate lags by one step per robot (the linear delay of §2.5.1.2); offline, the modules simply
run in order over the whole run, module k stopping k steps before the end.

What the Tail knows: its own position and Follower 1's position at every step, and every
robot's true pose at step 0 (τ) and, with intermittent communication (§2.5.3.2), at every
`comm_every`-th step. Nothing else from the truth enters the loop.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from estimators.retlo.chain import module_steps, report_names, unseen_errors
from estimators.retlo.frames import extrapolate_2x
from estimators.retlo_sim.frames import decode, module_base

Predict = Callable[[np.ndarray], np.ndarray]   # base (B, 5) → (B, 3): x_H, y_H, θ_F@t+1


def sync_steps(steps: int, comm_every: int | None) -> np.ndarray:
    """Steps at which the Tail holds every true pose: τ = 0, then every `comm_every` steps."""
    return np.arange(0, steps, comm_every) if comm_every else np.array([0])


def estimate_chain(predict: Predict, sensed: np.ndarray, synced: np.ndarray,
                   sync: np.ndarray) -> np.ndarray:
    """Estimated positions (S, N, 2), Tail first, NaN where nothing is estimated.

    sensed (S, 2, 2): the Tail's own and Follower 1's positions at every step, as sensed.
    synced (len(sync), N, 3): every pose (Tail first) received at the `sync` steps.
    """
    steps, n = len(sensed), synced.shape[1]
    pos = np.full((steps, n, 2), np.nan)
    theta = np.full((steps, n), np.nan)
    pos[:, :2] = sensed
    pos[sync, 2:] = synced[:, 2:, :2]
    theta[sync] = synced[:, :, 2]
    is_sync = np.zeros(steps + 1, bool)
    is_sync[sync] = True
    for k in range(n - 2):
        for t in module_steps(k, steps, 0):
            fol = np.append(pos[t, k + 1], theta[t, k + 1])[None]
            base, origin, alpha = module_base(pos[t, k][None], fol, pos[t + 1, k + 1][None])
            head_xy, fol_theta = decode(predict(base), origin, alpha)
            if not is_sync[t]:
                pos[t, k + 2] = head_xy[0]
            if not is_sync[t + 1]:
                theta[t + 1, k + 1] = fol_theta[0]
    return pos


class OnlineChain:
    """`estimate_chain` one step at a time, as a Tail runs it live: `start` with every true
    pose (Tail first) at τ, then `observe` its own and Follower 1's position each step, and
    `share` every pose when the team communicates (§2.5.3.2). After the observation of step s,
    module k runs at step s - 1 - k: its inputs are all there (robot k+1 at s - k came from
    module k-1 just before), so the estimates equal `estimate_chain`'s on the same observations
    and sync steps. `head` is the latest estimate of the Head: it lags n - 2 steps."""

    def __init__(self, predict: Predict, n: int, capacity: int):
        self.predict, self.n = predict, n
        self.pos = np.full((capacity, n, 2), np.nan)
        self.theta = np.full((capacity, n), np.nan)
        self.synced = np.zeros(capacity + 1, bool)
        self.step = -1

    def start(self, poses: np.ndarray) -> None:
        """Every robot's true pose (n, 3), Tail first, at τ: step 0."""
        self.pos[:] = np.nan
        self.theta[:] = np.nan
        self.synced[:] = False
        self.step = 0
        self.pos[0, :2] = poses[:2, :2]
        self.share(poses)

    def share(self, poses: np.ndarray) -> None:
        """Every robot's true pose (n, 3), Tail first, at the latest step (a sync step)."""
        s = self.step
        self.pos[s, 2:], self.theta[s] = poses[2:, :2], poses[:, 2]
        self.synced[s] = True

    def observe(self, sensed: np.ndarray) -> None:
        """The Tail's and Follower 1's positions (2, 2) at the next step."""
        s = self.step = self.step + 1
        if s >= len(self.pos):
            raise ValueError(f"OnlineChain holds {len(self.pos)} steps; give a larger capacity")
        pos, theta = self.pos, self.theta
        pos[s, :2] = sensed
        for k in range(self.n - 2):
            t = s - 1 - k
            if t < 0:
                break
            fol = np.append(pos[t, k + 1], theta[t, k + 1])[None]
            base, origin, alpha = module_base(pos[t, k][None], fol, pos[t + 1, k + 1][None])
            head_xy, fol_theta = decode(self.predict(base), origin, alpha)
            if not self.synced[t]:
                pos[t, k + 2] = head_xy[0]
            if not self.synced[t + 1]:
                theta[t + 1, k + 1] = fol_theta[0]

    @property
    def head(self) -> tuple[int, np.ndarray]:
        """(step, position) of the latest Head estimate (step 0: the truth at τ)."""
        t = max(0, self.step - (self.n - 2))
        return t, self.pos[t, -1]


def estimate_heuristic(sensed: np.ndarray, synced: np.ndarray, sync: np.ndarray) -> np.ndarray:
    """The 2X heuristic applied modularly (robot k+2 ≈ robot k + 2 (robot k+1 − robot k)),
    with the knowledge of `estimate_chain` (memoryless between syncs): a reference for how much
    the networks add."""
    steps, n = len(sensed), synced.shape[1]
    pos = np.full((steps, n, 2), np.nan)
    pos[:, :2] = sensed
    for k in range(n - 2):
        pos[:, k + 2] = extrapolate_2x(pos[:, k], pos[:, k + 1])
        pos[sync, k + 2] = synced[:, k + 2, :2]
    return pos


def one_step_errors(predict: Predict, truth: np.ndarray) -> np.ndarray:
    """Error (S - 1,) of robot 2 when module 0 gets true inputs at every step (true θ_F, no
    recursion): separates what the networks get wrong from what the recursion accumulates."""
    base, origin, alpha = module_base(truth[:-1, 0, :2], truth[:-1, 1], truth[1:, 1, :2])
    head_xy, _ = decode(predict(base), origin, alpha)
    return np.linalg.norm(head_xy - truth[:-1, 2, :2], axis=-1)


def chain_errors(est: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """Euclidean error (S, N-2) of every robot the Tail cannot see (robots 2.., Tail first),
    NaN at τ and where no estimate exists (the last steps of far robots)."""
    err = unseen_errors(est, truth[..., :2])
    err[0] = np.nan
    return err


def summarize(err: np.ndarray, names: list[str], threshold: float) -> dict:
    """Per robot and overall: mean error and the share of steps under `threshold`."""
    def stats(e: np.ndarray) -> dict:
        e = e[np.isfinite(e)]
        return {"mean_error": float(e.mean()), "max_error": float(e.max()),
                "share_under": float((e < threshold).mean()), "steps": int(e.size)}

    return {"per_robot": {nm: stats(err[:, j]) for j, nm in enumerate(names)},
            "all": stats(err.ravel())}


def unseen_names(n: int) -> list[str]:
    """Names of robots 2.. (Tail first), as the reports of both chapters call them."""
    return report_names(n)[2:]
