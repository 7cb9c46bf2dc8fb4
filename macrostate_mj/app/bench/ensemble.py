"""`bench --only ensemble`: K ReTLo networks trained together (`estimators.retlo.ensemble`)
against the same K trained one after another, in the same run, for K = 1, 3, 9, 27.

Both ways train the very same jobs (synthetic 3-robot chains, one dataset and seed per model,
chapter 3's settings but for the epochs), so the ratio is the batching's alone. Two networks:
chapter 3's LSTM (unidirectional, cos/sin) and the FC baseline.

Why the two gain so differently is a figure too, `arithmetic`: each network's training step
(forward and backward of one batch) in GFLOP/s against one thread's float32 matrix product in
the same run. Batching removes per-call overhead, not arithmetic, so a step already near the
matrix product's rate (the LSTM) has little left to gain; one far below it (FC) has much.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from macrostate_mj.app.bench import SUITES, figure

KS = (1, 3, 9, 27)
INSTANCES, VAL, EPOCHS = 24, 8, 2
MATMUL = 1024          # the reference: one (MATMUL x MATMUL) float32 product, one thread


def _model(kind: str) -> Any:
    from estimators.retlo.models import ModelConfig

    return (ModelConfig(history=10, bidirectional=False, cos_sin=True) if kind == "lstm"
            else ModelConfig(kind="fc"))


def _jobs(k: int, kind: str) -> list:
    from estimators.retlo.ensemble import Job
    from estimators.retlo.synthetic import synthetic_chains
    from estimators.retlo.train import TrainConfig

    model = _model(kind)
    val = synthetic_chains(VAL, 3, 10_000)
    return [Job([synthetic_chains(INSTANCES, 3, i)], val,
                TrainConfig(epochs=EPOCHS, patience=EPOCHS, seed=i, model=model))
            for i in range(k)]


@SUITES.register("ensemble", rank=120)
def bench_ensemble(ks: tuple[int, ...] = KS) -> list[dict]:
    """Per network and K: the speed-up of training K together over K one after another."""
    from estimators.retlo.ensemble import train_many
    from estimators.retlo.train import train

    out = []
    for kind in ("lstm", "fc"):
        warm = _jobs(1, kind)[0]
        train(warm.train, warm.val, warm.cfg, progress=False)      # first-call costs aside
        for k in ks:
            jobs = _jobs(k, kind)
            t0 = time.perf_counter()
            for job in jobs:
                train(job.train, job.val, job.cfg, progress=False)
            alone = time.perf_counter() - t0
            t0 = time.perf_counter()
            train_many(jobs)
            together = time.perf_counter() - t0
            config = {"k": k, "model": kind, "instances": INSTANCES, "epochs": EPOCHS,
                      "alone_s": round(alone, 3), "together_s": round(together, 3)}
            out.append(figure("speedup", alone / together, "x vs one after another",
                              config=config))
    return out + bench_arithmetic()


def _seconds(fn: Callable[[], object], seconds: float = 0.5) -> float:
    """Median seconds of one call of `fn` over calls filling about `seconds` (after one)."""
    import numpy as np

    fn()
    times: list[float] = []
    while sum(times) < seconds or len(times) < 5:
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


class _Step:
    """One training step (forward and backward, no optimizer) of a fresh network of `kind`
    on a fixed random batch: what `arithmetic` both counts and times."""

    def __init__(self, kind: str, batch: int) -> None:
        import torch

        from estimators.retlo.models import RetloNet

        self.net = RetloNet(_model(kind), 1.0)
        g = torch.Generator().manual_seed(0)
        self.lstm = getattr(self.net, "f_hist", None)
        width = self.lstm.input_size if self.lstm is not None else 9    # FC reads no history
        self.obs = torch.randn(batch, 4, generator=g)
        self.hist = torch.randn(batch, self.net.cfg.history, width, generator=g)

    def __call__(self) -> None:
        self.net.zero_grad()
        pos, ang = self.net(self.obs, self.hist)
        (pos.sum() + ang.sum()).backward()

    def flops(self) -> float:
        """Its linear layers as torch's counter counts them, its LSTM (which that counter does
        not see) as 3 x its forward's 2 x batch x steps x 4m x (inputs + m) per direction."""
        from torch.utils.flop_counter import FlopCounterMode

        with FlopCounterMode(display=False) as counter:
            self()
        flops = float(counter.get_total_flops())
        if self.lstm is not None:
            lstm, (batch, steps, _) = self.lstm, self.hist.shape
            per_step = 2 * 4 * lstm.hidden_size * (lstm.input_size + lstm.hidden_size)
            flops += 3 * batch * steps * per_step * (2 if lstm.bidirectional else 1)
        return flops


def step_flops(kind: str, batch: int) -> float:
    """Floating-point operations of one training step (forward and backward) of the network."""
    return _Step(kind, batch).flops()


def bench_arithmetic(batch: int = 64) -> list[dict]:
    """Per network: its training step's GFLOP/s against one thread's float32 matrix product
    (`MATMUL` square) in the same run; ratio near 1: bound by arithmetic, which batching
    cannot remove."""
    import torch

    old = torch.get_num_threads()
    torch.set_num_threads(1)                  # as every training runs (`TrainConfig.threads`)
    try:
        a, b = torch.randn(MATMUL, MATMUL), torch.randn(MATMUL, MATMUL)
        limit = 2 * MATMUL ** 3 / _seconds(lambda: a @ b) / 1e9
        out = []
        for kind in ("lstm", "fc"):
            step = _Step(kind, batch)
            rate = step.flops() / _seconds(step) / 1e9
            out.append(figure("arithmetic", rate, "GFLOP/s", limit,
                              config={"model": kind, "batch": batch},
                              limit_name=f"one thread's float32 {MATMUL}x{MATMUL} matrix product"))
        return out
    finally:
        torch.set_num_threads(old)
