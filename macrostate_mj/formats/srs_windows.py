"""The SRS novelty models' input (seed §3.3.1): short windows of the Tail's module, as features.

A window is `WINDOW` consecutive log steps of the Tail's module: its Follower F and the robot
beyond, H (in a 3-robot team, the Head). Each step becomes 8 features: F's position (cm) and
cos, sin of its heading, then H's, all in the frame of the Tail at the window's last step
(`core.frames`: origin at the Tail, x along Tail→F). h′_t of §3.3.1 is such a window (ℓ − 1 = 9
steps for ℓ = 10); the step after it is the next-step predictor ζ's target, in the same frame.
Pure numpy: the collector scores windows online with these, the estimator trains on them; the
two meet only through `NoveltyScorer` and `NoveltySource` (independent layers, see pyproject).
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from macrostate_mj.core.frames import frame_of, from_frame, to_frame

WINDOW = 9          # ℓ − 1 steps (§3.3.1: h′_t drops the latest of ℓ = 10)
FEATURES = 8        # per step: F (x, y, cos, sin), H (x, y, cos, sin)
CM = 100.0


class NoveltyScorer(Protocol):
    """What the SR phase's Tail asks of the novelty models (φ, ψ, ζ), in these windows'
    features: enough to hallucinate the next step and score candidates, nothing of training."""

    def predict_next(self, windows: np.ndarray) -> np.ndarray:
        """ζ(φ(h′)): the step after each window (B, WINDOW, 8) -> (B, 8), in its frame."""
        ...

    def novelty(self, windows: np.ndarray) -> np.ndarray:
        """e, the novelty index, of each window (B, WINDOW, 8) -> (B,)."""
        ...


class NoveltySource(Protocol):
    """A stored scorer that each episode loads where it runs (a worker, a Ray node): it must
    pickle, and be a dataclass, since the collection's plan records its fields."""

    def load(self) -> NoveltyScorer: ...


def module_of(poses: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(..., n, 3) team poses (Head first, Tail last) -> the Tail's module (T, F, H), each
    (..., 3): the last three robots."""
    return poses[..., -1, :], poses[..., -2, :], poses[..., -3, :]


def step_features(fol: np.ndarray, head: np.ndarray, origin: np.ndarray, alpha: np.ndarray
                  ) -> np.ndarray:
    """World poses (*batch, *steps, 3) of F and H -> (*batch, *steps, 8) features in the
    frames (origin (*batch, 2) m, alpha (*batch))."""
    parts = []
    for robot in (fol, head):
        xy = to_frame(robot[..., :2], origin, alpha) * CM
        rel = robot[..., 2] - np.reshape(alpha, np.shape(alpha) + (1,) * (robot.ndim - 1
                                                                        - np.ndim(alpha)))
        parts += [xy, np.cos(rel)[..., None], np.sin(rel)[..., None]]
    return np.concatenate(parts, axis=-1)


def features_to_poses(feat: np.ndarray, origin: np.ndarray, alpha: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of `step_features` for one step per batch item: (*batch, 8) -> F and H world
    poses (*batch, 3)."""
    out = []
    for k in (0, 4):
        xy = from_frame(feat[..., k:k + 2] / CM, origin, alpha)
        theta = np.arctan2(feat[..., k + 3], feat[..., k + 2]) + alpha
        out.append(np.concatenate([xy, theta[..., None]], axis=-1))
    return out[0], out[1]


def window_features(tail: np.ndarray, fol: np.ndarray, head: np.ndarray) -> np.ndarray:
    """(*batch, WINDOW, 3) world poses of T, F, H -> (*batch, WINDOW, 8), in the frame of the
    Tail at the window's last step."""
    origin, alpha = frame_of(tail[..., -1, :2], fol[..., -1, :2])
    return step_features(fol, head, origin, alpha)


def training_windows(tracks: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Team tracks (instances, steps, n, 3) -> every window h′ (W, WINDOW, 8) and the step
    after it (W, 8) in the window's frame: the autoencoder's input and ζ's target."""
    tail, fol, head = module_of(np.asarray(tracks, np.float64))
    steps = tracks.shape[1]
    xs, ys = [], []
    for s in range(steps - WINDOW):
        win = slice(s, s + WINDOW)
        origin, alpha = frame_of(tail[:, s + WINDOW - 1, :2], fol[:, s + WINDOW - 1, :2])
        xs.append(step_features(fol[:, win], head[:, win], origin, alpha))
        ys.append(step_features(fol[:, s + WINDOW], head[:, s + WINDOW], origin, alpha))
    return np.concatenate(xs), np.concatenate(ys)
