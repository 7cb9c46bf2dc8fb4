"""IO-GEN pipeline time for one split, estimated from short slices of every stage."""

from __future__ import annotations

import time
from typing import TYPE_CHECKING

import numpy as np

from macrostate_mj.app.bench import SUITES, figure

if TYPE_CHECKING:
    from estimators.oneclass.train import OCConfig

TARGET_MIN = 45.0   # the one-split time target (minutes): a goal, not a measured limit


def _stage_seconds(x: np.ndarray, probe: OCConfig) -> dict[str, float]:
    """Seconds of each stage's last unit in `probe` (an epoch, or `GAN_TICK` steps): the first is
    left out, since it pays one-off costs (bfloat16 kernels are built on first use)."""
    import torch

    from estimators.oneclass import fit

    stamps: dict[str, list[float]] = {}

    def tick(stage: str, frac: float) -> None:
        stamps.setdefault(stage, []).append(time.perf_counter())

    old = torch.get_num_threads()
    try:
        fit(x, ("iogen",), probe, tick)
    finally:
        torch.set_num_threads(old)
    return {stage: times[-1] - times[-2] for stage, times in stamps.items()}


@SUITES.register("iogen", rank=100)
def bench_iogen(n_train: int = 960, threads: int = 2) -> list[dict]:
    """Estimated wall time of one split's IO-GEN pipeline (default recipe, m = 2) on this CPU,
    in float32 and in bfloat16 mixed precision (`--precision bf16`).

    Runs two epochs (20 GAN steps) of every stage on random inputs of the real size and
    extrapolates the second epoch (the last ten steps) to the default counts; the float32
    limit is the 45-minute target (`limit_kind` "target"), the bfloat16 one the float32
    estimate of the same run (its ratio is the speed-up).
    """
    import dataclasses

    from estimators.oneclass.train import GAN_TICK, OCConfig

    full = OCConfig(threads=threads)
    probe = dataclasses.replace(full, dcae_epochs=2, dsvdd_epochs=2, gan_steps=2 * GAN_TICK,
                                cls_epochs=2)
    x = (np.random.default_rng(0).normal(0, 0.02, (n_train, 4, 64, 64))).astype(np.float32)
    spans = {p: _stage_seconds(x, dataclasses.replace(probe, precision=p))
             for p in ("fp32", "bf16")}

    def estimate(cfg: OCConfig, precision: str = "fp32") -> float:
        s = spans[precision]
        return (s["DCAE"] * cfg.dcae_epochs + s["DSVDD"] * cfg.dsvdd_epochs
                + s["IOGEN"] / GAN_TICK * cfg.gan_steps + s["CLS-IOGEN"] * cfg.cls_epochs)

    published = OCConfig.recipe("published", threads=threads)
    return [figure("iogen_one_split_minutes_estimate", estimate(full) / 60, "min", TARGET_MIN,
                   config=f"short recipe, {threads} threads; limit: the {TARGET_MIN:g}-minute "
                   "target, not a measured floor", lower_is_better=True, fixed_target=True),
            figure("iogen_bf16_one_split_minutes_estimate", estimate(full, "bf16") / 60, "min",
                   estimate(full) / 60, config=f"short recipe, {threads} threads, --precision "
                   "bf16; limit: the float32 estimate of the same run", lower_is_better=True),
            figure("iogen_published_recipe_one_split_minutes_estimate",
                   estimate(published) / 60, "min",
                   config=f"published recipe (DCAE {published.dcae_epochs}, DSVDD "
                   f"{published.dsvdd_epochs}, GAN {published.gan_steps} steps, classifier "
                   f"{published.cls_epochs}), {threads} threads")]
