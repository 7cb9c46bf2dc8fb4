"""The SR phase's cost against passive collection of the same episodes (the issue's bound: 2x)."""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from macrostate_mj.app.bench import SUITES, figure


@SUITES.register("srs", rank=110)
def bench_srs(seconds: float = 120.0, k: int = 30, repeats: int = 2) -> list[dict]:
    """One webots 3-robot episode collected passively, then with the SRS Tail (k candidates,
    SRS-Max; a model of the default size with seeded weights: its cost does not depend on
    them), on one worker; best of `repeats`, alternated."""
    import torch

    from collectors.episodes import EpisodeSpec, run_episode
    from estimators.srs.novelty import (
        NoveltyConfig,
        NoveltyFile,
        NoveltyModel,
        NoveltyNet,
        save_novelty,
    )
    from macrostate_mj.chain.scenarios import SCENARIOS
    from macrostate_mj.tails.collection import PolicyConfig
    from macrostate_mj.tails.srs import SRSConfig

    torch.manual_seed(0)
    with tempfile.TemporaryDirectory() as tmp:
        path = str(save_novelty(Path(tmp) / "m.pt", NoveltyModel(
            NoveltyNet(NoveltyConfig()), NoveltyConfig(), 3, "webots"), {}))
        srs = SRSConfig(NoveltyFile(path), "max", k)
        policies = {"passive": PolicyConfig("passive"), "srs": srs}
        webots = SCENARIOS["webots"]
        run_episode(EpisodeSpec(webots, 3, 5.0, 0.0, 0, 0))          # warm-up (imports, GL)
        best = dict.fromkeys(policies, np.inf)
        scored = 0
        for _ in range(repeats):
            for name, policy in policies.items():
                t0 = time.perf_counter()
                _, _, stats = run_episode(EpisodeSpec(webots, 3, seconds, 10.0, 0, 0, policy))
                best[name] = min(best[name], time.perf_counter() - t0)
                if stats["decisions"] is not None:
                    scored = stats["decisions"].num_rows
    tag = (f"webots, 3 robots, {seconds + 10:g} s episode, 1 worker, k={k}, {scored} scored "
           f"steps, best of {repeats}")
    return [figure("srs_episode_seconds", best["srs"], "s", 2 * best["passive"], config=tag,
                   lower_is_better=True, limit_name="2x the passive collection of the episode"),
            figure("srs_ms_per_scored_step", (best["srs"] - best["passive"]) / scored * 1000,
                   "ms", config=tag)]
