"""`bench --only ensemble`: K ReTLo networks trained together (`estimators.retlo.ensemble`)
against the same K trained one after another, in the same run, for K = 1, 3, 9, 27.

Both ways train the very same jobs (synthetic 3-robot chains, one dataset and seed per model,
chapter 3's settings but for the epochs), so the ratio is the batching's alone. Two networks:
chapter 3's LSTM (unidirectional, cos/sin) and the FC baseline.
"""

from __future__ import annotations

import time

from macrostate_mj.app.bench import figure

KS = (1, 3, 9, 27)
INSTANCES, VAL, EPOCHS = 24, 8, 2


def _jobs(k: int, kind: str) -> list:
    from estimators.retlo.ensemble import Job
    from estimators.retlo.models import ModelConfig
    from estimators.retlo.synthetic import synthetic_chains
    from estimators.retlo.train import TrainConfig

    model = (ModelConfig(history=10, bidirectional=False, cos_sin=True) if kind == "lstm"
             else ModelConfig(kind="fc"))
    val = synthetic_chains(VAL, 3, 10_000)
    return [Job([synthetic_chains(INSTANCES, 3, i)], val,
                TrainConfig(epochs=EPOCHS, patience=EPOCHS, seed=i, model=model))
            for i in range(k)]


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
    return out
