"""The three chained networks of §2.5.1.1, {ANN_x, ANN_y, ANN_θ}, in plain numpy.

Each is a 3-layer perceptron: inputs, 12 logistic-sigmoid hidden units, one linear output.
ANN_x sees the 5 one-step features (`frames.one_step_features`) plus a bias, ANN_y also x_H,
ANN_θ also x_H and y_H. In training, ANN_y and ANN_θ get the true x_H, y_H (the three are
trained independently, as the seed trains them); in use they get the chained estimates. The
three are stored as one stack whose input weights are masked, so one matrix product trains all
three at once. `OneStepModule` makes them (or any one-step function) a chain `Module`.

Inputs and targets are standardized with training statistics (the seed's tool, Weka, scales
them too): positions differ by millimetres while the chain is 8 cm long. Training is SGD with
momentum on mini-batches of squared error, every draw from the Generator it is given, so the
same seed gives the same weights bit for bit. numpy rather than torch: the nets have 100
weights each, and at that size numpy's per-step overhead is several times smaller.
"""

from __future__ import annotations

import io
import os
from collections.abc import Callable
from dataclasses import dataclass, fields
from typing import ClassVar

import numpy as np

from estimators.retlo.chain import Features, true_windows
from estimators.retlo.frames import FrameEstimate, Window, module_targets, one_step_features

HIDDEN = 12
N_IN = 7                                   # base (5) + x_H + y_H
MASK = np.array([[1] * 5 + [0, 0], [1] * 6 + [0], [1] * 7], np.float64)  # ANN_x, ANN_y, ANN_θ


def sigmoid(z: np.ndarray) -> np.ndarray:
    return 0.5 * (1.0 + np.tanh(0.5 * z))   # = 1 / (1 + e^-z) without overflow warnings


class OneStepModule:
    """§2.5's module as a chain `Module`: any `predict(base (B, 5)) -> (B, 3)` = x_H, y_H,
    θ_F@t+1 in the frame, from the Follower's pose at t and position at t+1 alone."""

    history: ClassVar[int] = 0
    rotate: ClassVar[bool] = True

    def predict(self, base: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def features(self, win: Window) -> Features:
        return (one_step_features(win),)

    def estimate(self, x: Features) -> FrameEstimate:
        out = self.predict(x[0])
        return FrameEstimate(out[:, :2], fol_theta_next=out[:, 2])


def training_pairs(poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(base, targets) of every step pair of 3-robot runs: poses (..., S, 3, 3) in the pose
    log's order (H, F1, T), metres → base (M, 5), targets (M, 3) = x_H, y_H, θ_F@t+1 with
    M = runs · (S - 1), run-major."""
    p = np.asarray(poses, np.float64).reshape(-1, *poses.shape[-3:])[:, :, ::-1]   # Tail first
    win = true_windows(p, 0, 0, OneStepModule.rotate)
    pos, ang = module_targets(win.head[:, 0], win.fol[:, 0], win.fol[:, 1], win.origin,
                              win.alpha)
    return one_step_features(win), np.concatenate([pos, ang[:, 2:]], axis=-1)


@dataclass
class ChainedMLP(OneStepModule):
    """Weights of the three nets (stacked on axis 0) and the standardization they expect."""

    w1: np.ndarray      # (3, 7, 12), zero where MASK is 0
    b1: np.ndarray      # (3, 12)     the seed's bias input
    w2: np.ndarray      # (3, 12)
    b2: np.ndarray      # (3,)
    x_mean: np.ndarray  # (7,)
    x_std: np.ndarray   # (7,)
    y_mean: np.ndarray  # (3,)
    y_std: np.ndarray   # (3,)

    def predict(self, base: np.ndarray) -> np.ndarray:
        """Chained prediction (B, 3) = x_H, y_H, θ_F@t+1 from base features (B, 5)."""
        x = np.zeros((len(base), N_IN))
        x[:, :5] = base
        x = (x - self.x_mean) / self.x_std
        out = np.empty((len(base), 3))
        for k in range(3):
            h = sigmoid(x @ self.w1[k] + self.b1[k])
            out[:, k] = (h @ self.w2[k] + self.b2[k]) * self.y_std[k] + self.y_mean[k]
            if k < 2:   # feed the estimate to the next net, scaled as that input was in training
                x[:, 5 + k] = (out[:, k] - self.x_mean[5 + k]) / self.x_std[5 + k]
        return out

    def to_npz(self) -> bytes:
        """Its arrays as .npz bytes: `from_npz` rebuilds it without unpickling anything."""
        buf = io.BytesIO()
        np.savez(buf, **{f.name: getattr(self, f.name) for f in fields(self)})
        return buf.getvalue()

    @classmethod
    def from_npz(cls, path: str | os.PathLike) -> ChainedMLP:
        with np.load(path, allow_pickle=False) as z:
            return cls(**{k: z[k] for k in z.files})


def init_mlp(x: np.ndarray, y: np.ndarray, rng: np.random.Generator) -> ChainedMLP:
    """Random weights (uniform ±1/√fan-in) and the standardization of inputs x (M, 7) and
    targets y (M, 3). A constant input (the frame's y_F = 0) keeps std 1 instead of 0."""
    x_std = x.std(0)
    x_std[x_std < 1e-12] = 1.0
    fan = MASK.sum(1)[:, None, None]
    w1 = rng.uniform(-1, 1, (3, N_IN, HIDDEN)) / np.sqrt(fan) * MASK[:, :, None]
    b1 = rng.uniform(-1, 1, (3, HIDDEN)) / np.sqrt(fan[:, 0])
    w2 = rng.uniform(-1, 1, (3, HIDDEN)) / np.sqrt(HIDDEN)
    return ChainedMLP(w1, b1, w2, np.zeros(3), x.mean(0), x_std, y.mean(0), y.std(0))


def loss_and_grads(m: ChainedMLP, x: np.ndarray, y: np.ndarray
                   ) -> tuple[np.ndarray, list[np.ndarray]]:
    """Mean squared error per net (3,) on standardized data (B, 7), (B, 3), and its gradients
    with respect to (w1, b1, w2, b2) (a half factor absorbed)."""
    h = sigmoid(np.matmul(x, m.w1) + m.b1[:, None, :])                       # (3, B, 12)
    err = np.matmul(h, m.w2[:, :, None])[..., 0] + m.b2[:, None] - y.T        # (3, B)
    g = err / len(x)
    dz = g[:, :, None] * m.w2[:, None, :] * h * (1.0 - h)                    # (3, B, 12)
    grads = [np.matmul(x.T, dz) * MASK[:, :, None], dz.sum(1),
             np.matmul(g[:, None, :], h)[:, 0], g.sum(1)]
    return (err ** 2).mean(1), grads


def standardize(m: ChainedMLP, base: np.ndarray, targets: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
    """Training inputs (M, 7) (base plus the true x_H, y_H) and targets (M, 3), standardized."""
    x = np.concatenate([base, targets[:, :2]], axis=1)
    return (x - m.x_mean) / m.x_std, (targets - m.y_mean) / m.y_std


def train_mlp(base: np.ndarray, targets: np.ndarray, rng: np.random.Generator, epochs: int = 500,
              lr: float = 0.05, momentum: float = 0.2, batch: int = 32,
              progress: Callable[[int, int], None] | None = None
              ) -> tuple[ChainedMLP, np.ndarray]:
    """Train the three nets (§2.5.2.1: 500 epochs, lr 0.05, momentum 0.2); returns the model
    and the mean training loss per epoch and net (epochs, 3), in standardized units."""
    m = init_mlp(np.concatenate([base, targets[:, :2]], axis=1), targets, rng)
    x, y = standardize(m, base, targets)
    params = [m.w1, m.b1, m.w2, m.b2]
    vel = [np.zeros_like(p) for p in params]
    history = np.zeros((epochs, 3))
    for epoch in range(epochs):
        order = rng.permutation(len(x))
        total = np.zeros(3)
        for start in range(0, len(x), batch):
            idx = order[start:start + batch]
            loss, grads = loss_and_grads(m, x[idx], y[idx])
            total += loss * len(idx)
            for p, v, g in zip(params, vel, grads, strict=True):
                v *= momentum
                v -= lr * g
                p += v
        history[epoch] = total / len(x)
        if progress:
            progress(epoch + 1, epochs)
    return m, history


def mse(m: ChainedMLP, base: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """Mean squared error per output (3,) of the chained prediction, in the targets' units."""
    return ((m.predict(base) - targets) ** 2).mean(0)


def fit_runs(runs: list[np.ndarray], rng: np.random.Generator, epochs: int) -> ChainedMLP:
    """The three MLPs trained on pose runs (each (R, steps, 3, 3), Head first), with the
    hyper-parameters of §2.5.2.1 (learning rate 0.05, 20 % held out, batches of 128)."""
    base, targets = (np.concatenate(a) for a in zip(*map(training_pairs, runs), strict=True))
    model, _ = train_mlp(base, targets, rng, epochs, 0.05, 0.2, 128)
    return model
