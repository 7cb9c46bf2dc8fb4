"""K ReTLo networks of one shape trained as one: what makes chapter 3's hundreds of small
models affordable on a CPU.

A small network on a CPU spends most of a training step on per-call overhead (the dispatcher,
autograd bookkeeping, the optimizer's loop over tensors), not arithmetic. `StackedNet` holds K
`RetloNet`s' weights as (K, ...) tensors and runs them with batched matrix products, so one
step pays that overhead once for all K. `train_many` trains them exactly as `train.train`
trains each alone: the same initial weights (each built under its own seed), the same data
order, mirror flips and fed-back samples (each model draws from its own Generator in the same
sequence), its own closed-loop validation and early stopping, Adam's per-element updates on
its own gradients. Only the summation order of the products differs, so the twins agree to
float32 rounding at first and drift apart slowly (`tests/estimators/test_ensemble.py`
measures how far; the bench `ensemble` suite how much faster it is).

The LSTMs stay K fused PyTorch modules (see `StackedNet`): an LSTM of chapter 3's width is
bound by arithmetic on a CPU, so batching buys little there; the linear layers, the optimizer,
the data handling and the closed loops are batched.
"""

from __future__ import annotations

import copy
import time
from dataclasses import dataclass, replace

import numpy as np
import torch
from torch import nn

from estimators.retlo import CM_PER_M
from estimators.retlo.chain import Features, check_training_chains, predict_chain
from estimators.retlo.frames import FrameEstimate, Window
from estimators.retlo.models import RetloNet, decode_angles, net_features
from estimators.retlo.report import chain_report
from estimators.retlo.train import (
    TrainConfig,
    _append,
    as_chained,
    errors,
    make_samples,
    mean_spacing,
    mirror_signs,
)
from macrostate_mj.core.errors import UserError


class StackedNet(nn.Module):
    """K `RetloNet`s of one `ModelConfig` as one module: each parameter of theirs stacked on a
    new first axis, inputs and outputs (K, B, ...)."""

    def __init__(self, nets: list[RetloNet]) -> None:
        super().__init__()
        cfgs = {n.cfg for n in nets}
        if len(cfgs) != 1:
            raise UserError("stacked networks must share one ModelConfig")
        if any(n.head.uncertain for n in nets):   # StackedPredictor reads a point output
            raise UserError("stacked training is for point models; train Gaussian ones alone")
        self.cfg = nets[0].cfg
        self.k = len(nets)
        states = [n.state_dict() for n in nets]
        self.names = [name for name, _ in nets[0].named_parameters()
                      if not name.startswith("f_hist.")]
        self.weights = nn.ParameterList(
            nn.Parameter(torch.stack([s[name].detach() for s in states]).clone())
            for name in self.names)
        self.register_buffer("pos_scale", torch.stack([s["pos_scale"] for s in states]))
        # The LSTMs stay K modules: PyTorch's fused CPU LSTM beats any batched re-write of it
        # (its work is arithmetic, not overhead: `bench --only ensemble` measured 0.5x for
        # one written out with batched products at K = 27).
        self.lstms = nn.ModuleList(copy.deepcopy(n.f_hist) for n in nets
                                   if getattr(n, "f_hist", None) is not None)
        self._template = copy.deepcopy(nets[0])

    def _w(self, name: str) -> torch.Tensor:
        return self.weights[self.names.index(name)]

    def _linear(self, prefix: str, x: torch.Tensor) -> torch.Tensor:
        """nn.Linear per model: x (K, B, in) -> (K, B, out)."""
        w, b = self._w(f"{prefix}.weight"), self._w(f"{prefix}.bias")
        return torch.baddbmm(b.unsqueeze(1), x, w.transpose(1, 2))

    def forward(self, obs: torch.Tensor, hist: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """As `RetloNet.forward`, per model: obs (K, B, 4), hist (K, B, ℓ, F) -> scaled
        position (K, B, 2) and raw angles (K, B, 3) or (K, B, 3, 2)."""
        cfg = self.cfg
        scale = self.pos_scale.view(-1, 1, 1)
        obs = obs / scale
        hist = hist.clone()
        n_ang = 2 if cfg.cos_sin else 1
        for start in (0, 2 + n_ang):
            hist[..., start:start + 2] = hist[..., start:start + 2] / scale.unsqueeze(-1)
        feats = [torch.relu(self._linear("f_obs.0", obs))]
        if cfg.reads_history:
            finals = []
            for lstm, h in zip(self.lstms, hist, strict=True):
                _, (h_n, _) = lstm(h)
                finals.append(h_n.transpose(0, 1).reshape(len(h), -1))
            feats.append(torch.stack(finals))
        z = torch.relu(self._linear("fuse.0", torch.cat(feats, dim=-1)))
        ang = self._linear("g_theta", z)
        k, b = obs.shape[:2]
        return self._linear("g_p", z), ang.view(k, b, 3, 2) if cfg.cos_sin else ang

    def state_of(self, i: int) -> dict[str, torch.Tensor]:
        """Model i's weights as a `RetloNet` state dict (copies)."""
        state = {name: w[i].detach().clone() for name, w in zip(self.names, self.weights,
                                                                 strict=True)}
        if self.lstms:
            state |= {f"f_hist.{k}": v.detach().clone()
                      for k, v in self.lstms[i].state_dict().items()}
        return {**state, "pos_scale": self.pos_scale[i].clone()}

    def net(self, i: int, state: dict[str, torch.Tensor] | None = None) -> RetloNet:
        """Model i (or `state`, one of its `state_of`) as a plain `RetloNet`."""
        net = copy.deepcopy(self._template)
        net.load_state_dict(self.state_of(i) if state is None else state)
        return net.eval()


class StackedPredictor:
    """K stacked networks as one chain `Module` over K blocks of B runs: rows [iB, (i+1)B) of
    every batch are model i's. `predict_chain` treats runs independently, so chains tiled or
    concatenated K times come back as each model's own closed-loop predictions."""

    def __init__(self, net: StackedNet) -> None:
        self.net, self.cfg = net, net.cfg
        self.history, self.rotate = net.cfg.history, net.cfg.rotate

    def features(self, win: Window) -> Features:
        return net_features(win, self.cfg)

    @torch.no_grad()
    def estimate(self, x: Features) -> FrameEstimate:
        obs, hist = (torch.as_tensor(a, dtype=torch.float32) for a in x)
        k = self.net.k
        pos, ang = self.net(obs.view(k, -1, *obs.shape[1:]), hist.view(k, -1, *hist.shape[1:]))
        pos = (pos * self.net.pos_scale.view(-1, 1, 1)).reshape(len(obs), 2)
        ang = ang.reshape(len(obs), *ang.shape[2:])
        ang = decode_angles(ang, self.cfg.cos_sin).double().numpy()
        return FrameEstimate(pos.double().numpy() / CM_PER_M, head_theta=ang[:, 1],
                             fol_theta=ang[:, 0])


@dataclass(frozen=True)
class Job:
    """One model to train: its chains (B, S, N, 3) in metres and its settings."""

    train: list[np.ndarray]
    val: np.ndarray
    cfg: TrainConfig


def stackable(jobs: list[Job]) -> str | None:
    """Why `jobs` cannot be trained together (None when they can): one shape of model and
    settings but the seed, and data of one shape (so every step has K equal batches)."""
    first = jobs[0]
    for job in jobs[1:]:
        if replace(job.cfg, seed=0) != replace(first.cfg, seed=0):
            return "their settings differ beyond the seed"
        if [w.shape for w in job.train] != [w.shape for w in first.train]:
            return "their training chains differ in shape"
        if job.val.shape != first.val.shape:
            return "their validation chains differ in shape"
    return None


def _feedback(predictor: StackedPredictor, jobs: list[Job], rngs: list[np.random.Generator],
              chained: bool) -> list[dict[str, np.ndarray]]:
    """`train._with_feedback`'s samples for each model, from one batched closed loop: per
    training file, the K models' chains side by side, then split back per model."""
    k = len(jobs)
    out: list[dict[str, list[np.ndarray]]] = [{} for _ in range(k)]

    def closed_loop(worlds: list[np.ndarray]) -> np.ndarray:
        parts: dict[str, list[np.ndarray]] = {}
        stacked = np.concatenate(worlds)
        truth = stacked[:, :, ::-1]
        est = predict_chain(predictor, stacked,
                            lambda m, t, x, win: _append(parts, x, truth, m, t, win))
        for key, steps in parts.items():
            for i, rows in enumerate(_split(np.concatenate(steps), k, len(worlds[0]))):
                out[i].setdefault(key, []).append(rows)
        return est.reshape(k, -1, *est.shape[1:])

    for j in range(len(jobs[0].train)):
        worlds = [job.train[j] for job in jobs]
        est = closed_loop(worlds)
        if chained:
            closed_loop([as_chained(w, e, rng) for w, e, rng in zip(worlds, est, rngs,
                                                                    strict=True)])
    return [{key: np.concatenate(v).astype(np.float32) for key, v in o.items()} for o in out]


def _split(rows: np.ndarray, k: int, runs: int) -> list[np.ndarray]:
    """Samples recorded step by step on K models' runs side by side (each step's rows: model
    0's `runs`, then model 1's, ...) back per model, each in its own step order."""
    per = rows.reshape(-1, k, runs, *rows.shape[1:])
    return [per[:, i].reshape(-1, *rows.shape[1:]) for i in range(k)]


def _bases(jobs: list[Job]) -> list[dict[str, np.ndarray]]:
    """`train.make_samples` of every job's chains, featurised once for all K: each training
    file of the K jobs side by side, then split back per model (the same rows, bit for bit,
    in the same order as featurising each alone: `tests/estimators/test_ensemble.py`)."""
    k, model = len(jobs), jobs[0].cfg.model
    files = [(make_samples([np.concatenate([job.train[j] for job in jobs])], model),
              len(jobs[0].train[j])) for j in range(len(jobs[0].train))]
    per_file = [{key: _split(rows, k, runs) for key, rows in samples.items()}
                for samples, runs in files]
    return [{key: np.concatenate([f[key][i] for f in per_file]) for key in per_file[0]}
            for i in range(k)]


def _loss(pos: torch.Tensor, ang: torch.Tensor, batch: dict[str, torch.Tensor],
          net: StackedNet, angle_weight: float) -> torch.Tensor:
    """`train._loss` of each model (K,), on its own batch (K, b, ...)."""
    pos_err, ang_err = errors(pos, ang, batch, net.pos_scale.view(-1, 1, 1), net.cfg.cos_sin)
    return (pos_err.mean(dim=1)
            + angle_weight * ang_err.mean(dim=tuple(range(1, ang_err.dim()))))


def train_many(jobs: list[Job]) -> list[tuple[RetloNet, dict]]:
    """Train every job's model together (see the module docstring); per job, what
    `train.train` returns for it alone: the best closed-loop validation network and its
    record (best_val_cm, best_epoch, epochs_run, curve, ...)."""
    why = stackable(jobs)
    if why is not None:
        raise UserError(f"cannot train these {len(jobs)} models together: {why}")
    cfg = jobs[0].cfg
    for job in jobs:
        for i, w in enumerate(job.train):
            check_training_chains(w, cfg.model.history, what=f"training file {i + 1}")
        check_training_chains(job.val, cfg.model.history, what="validation file")
    torch.set_num_threads(cfg.threads)
    nets, rngs = [], []
    for job in jobs:                     # each built exactly as `train` builds it alone
        torch.manual_seed(job.cfg.seed)
        rngs.append(np.random.default_rng(job.cfg.seed))
        nets.append(RetloNet(cfg.model, CM_PER_M * mean_spacing(job.train)))
    bases = _bases(jobs)
    net = StackedNet(nets)
    predictor = StackedPredictor(net)
    signs = {k: torch.from_numpy(v).float() for k, v in mirror_signs(cfg.model).items()}
    opt = torch.optim.Adam(net.parameters(), lr=cfg.lr, foreach=True)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, T_max=cfg.epochs)
    k = len(jobs)
    best: list[tuple[float, int, dict | None]] = [(float("inf"), -1, None)] * k
    curves: list[list[dict]] = [[] for _ in range(k)]
    active = np.ones(k, bool)
    val = np.concatenate([job.val for job in jobs])
    start, batches = time.perf_counter(), 0
    for epoch in range(cfg.epochs):
        data = bases
        if cfg.feedback:
            net.eval()
            extra = _feedback(predictor, jobs, rngs, cfg.chained)
            data = [{key: np.concatenate([b[key], e[key]]) for key in b}
                    for b, e in zip(bases, extra, strict=True)]
        stacked = {key: torch.from_numpy(np.stack([d[key] for d in data])) for key in data[0]}
        totals, done = _epoch(net, opt, stacked, signs, rngs, cfg)
        batches += done
        sched.step()
        net.eval()
        est = predict_chain(predictor, val).reshape(k, -1, *val.shape[1:])
        for i in np.flatnonzero(active):
            val_cm = chain_report(est[i], jobs[i].val, cfg.model.history)["mean_error_cm"]
            curves[i].append({"epoch": epoch, "train_loss": float(totals[i]) / len(data[i]["obs"]),
                              "val_cm": val_cm})
            if val_cm < best[i][0]:
                best[i] = (val_cm, epoch, net.state_of(i))
            if epoch - best[i][1] >= cfg.patience:
                active[i] = False
        if not active.any():
            break
    seconds = time.perf_counter() - start
    out = []
    for i in range(k):
        info = {"best_val_cm": best[i][0], "best_epoch": best[i][1] + 1,
                "epochs_run": len(curves[i]), "train_seconds": seconds / k,
                "n_samples": len(bases[i]["obs"]), "batches": batches, "interrupted": False,
                "curve": curves[i], "trained_with": k}
        out.append((net.net(i, best[i][2]), info))
    return out


def _epoch(net: StackedNet, opt: torch.optim.Optimizer, data: dict[str, torch.Tensor],
           signs: dict[str, torch.Tensor], rngs: list[np.random.Generator], cfg: TrainConfig
           ) -> tuple[np.ndarray, int]:
    """`train._train_epoch` for K models at once: each its own shuffled order and mirror
    flips; summed loss per model, batches run."""
    net.train()
    k, n = data["obs"].shape[:2]
    orders = torch.from_numpy(np.stack([rng.permutation(n) for rng in rngs]))
    totals = np.zeros(k)
    flat = {key: v.reshape(k * n, *v.shape[2:]) for key, v in data.items()}
    orders += torch.arange(k)[:, None] * n          # model i's rows, in the flattened data
    done = 0
    for i in range(0, n, cfg.batch):
        idx = orders[:, i:i + cfg.batch]                       # (K, b)
        batch = {key: v.index_select(0, idx.reshape(-1)).view(*idx.shape, *v.shape[1:])
                 for key, v in flat.items()}
        if cfg.mirror:
            flip = torch.from_numpy(np.stack([rng.random(idx.shape[1]) < 0.5 for rng in rngs]))
            batch = {key: torch.where(flip.view(k, -1, *[1] * (v.dim() - 2)), v * signs[key], v)
                     for key, v in batch.items()}
        with cfg.autocast():
            pos, ang = net(batch["obs"], batch["hist"])
        loss = _loss(pos.float(), ang.float(), batch, net, cfg.angle_weight)
        opt.zero_grad()
        loss.sum().backward()
        opt.step()
        totals += loss.detach().double().numpy() * idx.shape[1]
        done += 1
    return totals, done
