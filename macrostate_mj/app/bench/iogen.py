"""IO-GEN pipeline time for one split, estimated from short slices of every stage."""

from __future__ import annotations

import time

import numpy as np

from macrostate_mj.app.bench import figure

TARGET_MIN = 45.0   # the one-split time target of issue 5 (minutes)



def bench_iogen(n_train: int = 960, threads: int = 2) -> list[dict]:
    """Estimated wall time of one split's IO-GEN pipeline (default recipe, m = 2) on this CPU.

    Runs a short slice of every stage on random inputs of the real size and extrapolates to the
    default epoch/step counts; the limit is the 45-minute target of issue 5.
    """
    import dataclasses

    import torch

    from estimators.oneclass import OCConfig, fit

    full = OCConfig(threads=threads)
    probe = dataclasses.replace(full, dcae_epochs=1, dsvdd_epochs=1, gan_steps=20, cls_epochs=1)
    x = (np.random.default_rng(0).normal(0, 0.02, (n_train, 4, 64, 64))).astype(np.float32)
    stamps: dict[str, float] = {}

    def tick(stage: str, frac: float) -> None:
        stamps[stage] = time.perf_counter()

    old = torch.get_num_threads()
    t0 = time.perf_counter()
    try:
        fit(x, ("iogen",), probe, tick)
    finally:
        torch.set_num_threads(old)
    order = ["DCAE", "DSVDD", "IOGEN", "CLS-IOGEN"]
    spans, prev = {}, t0
    for stage in order:
        spans[stage], prev = stamps[stage] - prev, stamps[stage]
    def estimate(cfg: OCConfig) -> float:
        return (spans["DCAE"] * cfg.dcae_epochs + spans["DSVDD"] * cfg.dsvdd_epochs
                + spans["IOGEN"] / probe.gan_steps * cfg.gan_steps
                + spans["CLS-IOGEN"] * cfg.cls_epochs)

    published = OCConfig.recipe("published", threads=threads)
    return [figure("iogen_one_split_minutes_estimate", estimate(full) / 60, "min", TARGET_MIN,
                   config=f"short recipe, {threads} threads; limit: the {TARGET_MIN:g}-minute "
                   "target, not a measured floor", lower_is_better=True),
            figure("iogen_published_recipe_one_split_minutes_estimate",
                   estimate(published) / 60, "min",
                   config=f"published recipe (DCAE {published.dcae_epochs}, DSVDD "
                   f"{published.dsvdd_epochs}, GAN {published.gan_steps} steps, classifier "
                   f"{published.cls_epochs}), {threads} threads")]
