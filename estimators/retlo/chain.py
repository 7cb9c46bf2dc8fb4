"""A 3-robot module applied along a chain (§2.5.1.2): the `Module` protocol, what the Tail holds
(`Tracks`), the one chain step both chapters and both modes (offline, live) run, and offline
inference.

Robots are indexed from the Tail here (0 = Tail, 1 = its observed neighbour, ..., N-1 = Head);
ThymioLoc files and pose logs list them from the Head. Module k takes robot k as its reference
(real or fictitious Tail), robot k+1 as its Follower and estimates robot k+2. Module k reads
robot k+1 at t+1, which module k-1 estimated one step later, so robot j is known up to step
S-j (the linear delay of §2.5.1.2); offline the modules simply run in order over a whole run.

Both chapters' modules (§2.5's one-step MLP, §2.6/§3.3's FC and LSTM with ℓ steps of history)
run through `module_step`; what differs is what the Tail knows: chapter 3 true poses until τ =
ℓ-1 over a batch of instances (`predict_chain`), chapter 2 true poses at sync steps of one run
(`estimate_chain`), and live the same one step at a time (`online.OnlineChain`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from estimators.retlo.frames import FrameEstimate, Window, decode, window_of
from estimators.retlo.gaussian import GAUSSIAN_REGIONS, Regions
from macrostate_mj.core.errors import UserError

Features = tuple[np.ndarray, ...]


class Module(Protocol):
    """One 3-robot module as the chain step drives it: its inputs from a `Window` of its robots,
    then an estimate in the module frame (metres, radians)."""

    history: int   # ℓ: steps before t it reads; 0 for §2.5's one-step module
    rotate: bool   # frame x axis along Tail→Follower (False: compass axes, §2.5.1.1)

    def features(self, win: Window) -> Features: ...

    def estimate(self, x: Features) -> FrameEstimate: ...


@dataclass(frozen=True)
class SplitChain:
    """Module 0 by one model and modules k >= 1 by another. Module 0's Follower is measured,
    every later module's is the module below's estimate: a model trained with chained
    Followers (`TrainConfig.chained`) is robust to that estimate's error but pays for it where
    the Follower is exact (docs: decisions/chained-training), so the first module runs a model
    trained without them. Alone (a 3-robot chain) it is its first module."""

    first: Module
    rest: Module

    def __post_init__(self) -> None:
        if (self.first.history, self.first.rotate) != (self.rest.history, self.rest.rotate):
            raise UserError("the first module's model and the later modules' differ in history "
                            "length or frame; train both with the same --history")

    @property
    def history(self) -> int:
        return self.first.history

    @property
    def rotate(self) -> bool:
        return self.first.rotate

    @property
    def uncertain(self) -> bool:
        """Whether both models' estimates carry a covariance."""
        return bool(getattr(self.first, "uncertain", False)
                    and getattr(self.rest, "uncertain", False))

    @property
    def regions(self) -> Regions:
        """The first model's region radii: fitted, like every model's, on 3-robot chains, where
        the first module is the only one."""
        return getattr(self.first, "regions", GAUSSIAN_REGIONS)

    def at(self, k: int) -> Module:
        return self.first if k == 0 else self.rest

    def features(self, win: Window) -> Features:
        return self.first.features(win)

    def estimate(self, x: Features) -> FrameEstimate:
        return self.first.estimate(x)


@dataclass
class Tracks:
    """What the Tail holds of its chain, Tail first, for B runs of S steps and N robots.

    pos (B, S, N, 2); each robot's heading twice, as the module that estimates it as its Head
    has it (`head_theta`) and as the module that sees it as its Follower has it (`fol_theta`),
    both (B, S, N): each module reads only its own heading estimates. `known` (S + 1,) marks
    steps whose poses are true (τ and before, sync steps): no estimate overwrites them.

    With an uncertain module, `cov` (B, S, N, 2, 2) holds each estimated position's covariance
    (NaN where true or not estimated). `noise` (B, N, 2), standard normal, makes each run a Monte
    Carlo particle (`propagate`): another module reads robot j at pos + L_j·noise_j (L_j the
    Cholesky factor of its covariance), one draw per run and robot for all steps.
    """

    pos: np.ndarray
    head_theta: np.ndarray
    fol_theta: np.ndarray
    known: np.ndarray
    cov: np.ndarray | None = None
    noise: np.ndarray | None = None


def empty_tracks(n_runs: int, n_steps: int, n_robots: int, with_cov: bool = False) -> Tracks:
    """Nothing known yet: every value NaN, no step true; `with_cov` keeps covariances too."""
    theta = np.full((n_runs, n_steps, n_robots), np.nan)
    return Tracks(np.full((n_runs, n_steps, n_robots, 2), np.nan), theta, theta.copy(),
                  np.zeros(n_steps + 1, bool), nan_covariances(theta.shape) if with_cov else None)


def nan_covariances(shape: tuple[int, ...]) -> np.ndarray:
    """Covariances (*shape, 2, 2), all NaN: nothing estimated yet."""
    return np.full((*shape, 2, 2), np.nan)


def tracks_from_world(world: np.ndarray, first: int) -> Tracks:
    """Chapter 3's knowledge from true poses (B, S, N, 3), Tail first: everything before step
    `first`, afterwards only the Tail's pose and its neighbour's position. Truth after τ is
    blanked, so a leak would surface as NaN rather than as a flattering error."""
    world = np.asarray(world, np.float64)
    pos, theta = world[..., :2].copy(), world[..., 2].copy()
    pos[:, first:, 2:] = np.nan
    theta[:, first:, 1:] = np.nan   # the neighbour's heading is not observed either
    return Tracks(pos, theta, theta.copy(), np.arange(world.shape[1] + 1) < first)


def sync_steps(steps: int, comm_every: int | None) -> np.ndarray:
    """Steps at which the Tail holds every true pose: τ = 0, then every `comm_every` steps."""
    return np.arange(0, steps, comm_every) if comm_every else np.array([0])


def tracks_from_view(sensed: np.ndarray, synced: np.ndarray, sync: np.ndarray) -> Tracks:
    """Chapter 2's knowledge of one run: sensed (S, 2, 2), the Tail's own and Follower 1's
    positions at every step as sensed; synced (len(sync), N, 3), every pose (Tail first)
    received at the `sync` steps (§2.5.3.2)."""
    tracks = empty_tracks(1, len(sensed), synced.shape[1])
    tracks.pos[0, :, :2] = sensed
    tracks.pos[0, sync, 2:] = synced[:, 2:, :2]
    tracks.head_theta[0, sync] = tracks.fol_theta[0, sync] = synced[:, :, 2]
    tracks.known[sync] = True
    return tracks


def first_estimate(history: int) -> int:
    """The first step a module estimates: after its ℓ true steps, and never τ = 0 itself."""
    return max(history, 1)


def module_steps(k: int, n_steps: int, first_step: int) -> range:
    """Steps module k runs at: from `first_step` until it runs out of input. Module k reads
    robot k+1 at t+1, which module k-1 estimated at its step t+1, so each module stops one step
    before the one below it (k steps before the end, less the step after t)."""
    return range(first_step, n_steps - 1 - k)


def window(tracks: Tracks, k: int, t: int, history: int, rotate: bool) -> Window:
    """Module k's window at step t: steps t-ℓ .. t+1 of robots k, k+1, k+2. The reference
    and the Follower are read as another module's inputs (`seen`); the Head's own track is its
    module's mean recursion."""
    lo, hi = t - history, t + 2
    fol = np.concatenate([seen(tracks, k + 1, lo, hi), tracks.fol_theta[:, lo:hi, k + 1, None]],
                         axis=-1)
    head = np.concatenate([tracks.pos[:, lo:hi, k + 2],
                           tracks.head_theta[:, lo:hi, k + 2, None]], axis=-1)
    return window_of(seen(tracks, k, lo, hi), fol, head, ~tracks.known[lo:t], rotate)


def seen(tracks: Tracks, j: int, lo: int, hi: int) -> np.ndarray:
    """Robot j's positions at steps lo..hi-1 as the next module reads them: the estimate, or
    in a Monte Carlo particle the estimate moved by the particle's draw where it has a
    covariance (true positions never move)."""
    pos = tracks.pos[:, lo:hi, j]
    if tracks.noise is None or tracks.cov is None:
        return pos
    cov = tracks.cov[:, lo:hi, j]
    has = np.isfinite(cov).all(axis=(-1, -2))
    chol = np.linalg.cholesky(np.where(has[..., None, None], cov, np.eye(2)))
    shift = (chol @ tracks.noise[:, None, j, :, None])[..., 0]
    return np.where(has[..., None], pos + shift, pos)


def module_step(module: Module, tracks: Tracks, k: int, t: int) -> tuple[Features, Window]:
    """Module k at step t, the one chain step: read its window, estimate, write every estimate
    into `tracks` except at known steps. Returns the module's inputs and window (for training
    on the model's own feedback)."""
    if isinstance(module, SplitChain):
        module = module.at(k)
    win = window(tracks, k, t, module.history, module.rotate)
    x = module.features(win)
    est = decode(module.estimate(x), win.origin, win.alpha)
    if not tracks.known[t]:
        tracks.pos[:, t, k + 2] = est.head_xy
        if tracks.cov is not None and est.head_cov is not None:
            tracks.cov[:, t, k + 2] = est.head_cov
        if est.head_theta is not None:
            tracks.head_theta[:, t, k + 2] = est.head_theta
        if est.fol_theta is not None:
            tracks.fol_theta[:, t, k + 1] = est.fol_theta
    if est.fol_theta_next is not None and not tracks.known[t + 1]:
        tracks.fol_theta[:, t + 1, k + 1] = est.fol_theta_next
    return x, win


Record = Callable[[int, int, Features, Window], None]   # (k, t, inputs, window) of each step


def run_chain(module: Module, tracks: Tracks, record: Record | None = None) -> Tracks:
    """Every module over every step it can reach, in order; `record` sees each step."""
    n_steps, n_robots = tracks.pos.shape[1:3]
    for k in range(n_robots - 2):
        for t in module_steps(k, n_steps, module.history):
            x, win = module_step(module, tracks, k, t)
            if record is not None:
                record(k, t, x, win)
    return tracks


def check_chain(shape: tuple[int, ...], history: int, what: str = "data") -> None:
    """Refuse chains the module cannot run on: not (B, S, N, 3), none, fewer than 3 robots, or
    no step after the history."""
    if len(shape) != 4 or shape[-1] != 3:
        raise UserError(f"{what} has shape {tuple(shape)}; chains are (instances, steps, robots, "
                        "3) poses (x, y, theta)")
    n_chains, n_steps, n_robots, _ = shape
    if n_chains == 0:
        raise UserError(f"{what} holds no chains; pass at least one instance")
    if n_robots < 3:
        raise UserError(f"{what} has {n_robots} robots; ReTLo needs chains of at least 3 "
                        "(Head, Follower, Tail)")
    if n_steps < history + 2:
        raise UserError(f"{what} has {n_steps} steps; the model needs at least {history + 2} "
                        f"({history} of history, then a step and the next observation)")


def check_training_chains(world: np.ndarray, history: int, what: str) -> None:
    """`check_chain`, and every pose finite: a NaN in training or validation chains would
    train and select on NaN losses without a word."""
    check_chain(world.shape, history, what)
    bad = ~np.isfinite(world)
    if bad.any():
        raise UserError(f"{what} holds {int(bad.sum())} NaN or infinite pose values (in "
                        f"{int(bad.any(axis=(1, 2, 3)).sum())} instances); drop or fill those "
                        "instances before training")


def predict_chain(module: Module, world: np.ndarray, record: Record | None = None
                  ) -> np.ndarray:
    """Estimate every robot the Tail cannot see, from true poses until τ and afterwards only the
    Tail's own pose and its neighbour's position (chapter 3).

    world: (B, S, N, 3) in file order (H, F1.., T), metres and radians. Returns the estimates in
    the same layout: NaN where nothing is estimated (the Tail; the neighbour's position; steps
    up to τ and the last steps a module cannot reach).
    """
    check_chain(world.shape, module.history)
    first = first_estimate(module.history)
    tracks = run_chain(module, tracks_from_world(world[:, :, ::-1], first), record)
    return chain_estimates(tracks, first)


def chain_estimates(tracks: Tracks, first: int) -> np.ndarray:
    """`predict_chain`'s layout (B, S, N, 3), file order, of what the chain estimated from
    step `first` on: the unseen robots' poses and the neighbour's heading, NaN elsewhere."""
    est = np.full((*tracks.pos.shape[:3], 3), np.nan)
    est[:, first:, 2:, :2] = tracks.pos[:, first:, 2:]
    est[:, first:, 2:, 2] = tracks.head_theta[:, first:, 2:]
    est[:, first:, 1, 2] = tracks.fol_theta[:, first:, 1]
    return est[:, :, ::-1]


def estimate_chain(module: Module, sensed: np.ndarray, synced: np.ndarray, sync: np.ndarray
                   ) -> np.ndarray:
    """Estimated positions (S, N, 2) of one run, Tail first, NaN where nothing is estimated
    (chapter 2; see `tracks_from_view` for what the Tail knows). Nothing else from the truth
    enters the loop."""
    return run_chain(module, tracks_from_view(sensed, synced, sync)).pos[0]


def true_windows(world: np.ndarray, k: int, history: int, rotate: bool) -> Window:
    """Module k's windows at every step it can take of true runs (R, S, N, 3), Tail first,
    batched run-major (R · (S-ℓ-1) windows): inputs for training and one-step errors."""
    n_runs, n_steps = world.shape[:2]
    steps = n_steps - history - 1
    idx = np.arange(steps)[:, None] + np.arange(history + 2)[None]    # (windows, ℓ+2)

    def of(j: int) -> np.ndarray:
        return world[:, idx, j].reshape(n_runs * steps, history + 2, 3)

    return window_of(of(k)[..., :2], of(k + 1), of(k + 2), np.zeros(history, bool), rotate)
