"""The chain estimator as a Tail runs it live (chapter 2's knowledge, `chain.tracks_from_view`):
the same `chain.module_step` as offline, one observation at a time."""

from __future__ import annotations

import numpy as np

from estimators.retlo.chain import Module, Tracks, empty_tracks, module_step


class OnlineChain:
    """`chain.estimate_chain` one step at a time: `start` with every true pose (Tail first) at
    τ, then `observe` the Tail's own and Follower 1's position each step, and `share` every pose
    when the team communicates (§2.5.3.2). After the observation of step s, module k runs at
    step s - 1 - k: its inputs are all there (robot k+1 at s - k came from module k-1 just
    before), so the estimates equal `estimate_chain`'s on the same observations and sync steps.
    `head` is the latest estimate of the Head: it lags n - 2 steps. An uncertain module's
    covariances are kept too (`head_cov`): each module's own, without the offline Monte Carlo
    of `propagate` (live, one run is all there is)."""

    def __init__(self, module: Module, n: int, capacity: int):
        self.module, self.n = module, n
        self.uncertain = bool(getattr(module, "uncertain", False))
        self.tracks: Tracks = empty_tracks(1, capacity, n, self.uncertain)
        self.step = -1

    @property
    def pos(self) -> np.ndarray:
        """Positions (capacity, n, 2) held so far, Tail first, NaN where nothing is known."""
        return self.tracks.pos[0]

    def start(self, poses: np.ndarray) -> None:
        """Every robot's true pose (n, 3), Tail first, at τ: step 0."""
        self.tracks = empty_tracks(*self.tracks.head_theta.shape, self.uncertain)
        self.step = 0
        self.pos[0, :2] = poses[:2, :2]
        self.share(poses)

    def share(self, poses: np.ndarray) -> None:
        """Every robot's true pose (n, 3), Tail first, at the latest step (a sync step)."""
        s, tracks = self.step, self.tracks
        tracks.pos[0, s, 2:] = poses[2:, :2]
        tracks.head_theta[0, s] = tracks.fol_theta[0, s] = poses[:, 2]
        tracks.known[s] = True

    def observe(self, sensed: np.ndarray) -> None:
        """The Tail's and Follower 1's positions (2, 2) at the next step."""
        s = self.step = self.step + 1
        if s >= len(self.pos):
            raise ValueError(f"OnlineChain holds {len(self.pos)} steps; give a larger capacity")
        self.pos[s, :2] = sensed
        for k in range(self.n - 2):
            t = s - 1 - k
            if t < self.module.history:
                break
            module_step(self.module, self.tracks, k, t)

    @property
    def history(self) -> int:
        """Steps of every pose the module reads before its first estimate (its window, ℓ): a
        live Tail is given them, as an instance's first ℓ steps are known."""
        return int(self.module.history)

    @property
    def head(self) -> tuple[int, np.ndarray]:
        """(step, position) of the latest Head estimate (step 0: the truth at τ)."""
        t = max(0, self.step - (self.n - 2))
        return t, self.pos[t, -1]

    @property
    def head_known(self) -> bool:
        """Whether `head` is the truth (τ or a sync step), not an estimate."""
        return bool(self.tracks.known[self.head[0]])

    @property
    def head_cov(self) -> np.ndarray | None:
        """Covariance (2, 2) of `head`'s position (m²): NaN at τ and sync steps (the truth),
        None for a point module."""
        if self.tracks.cov is None:
            return None
        return self.tracks.cov[0, self.head[0], -1]
