"""Environments that need an estimator (a layer above both `env` and `estimators`): what the
`LocalizeTail-v0` id makes."""

from __future__ import annotations

from pathlib import Path
from typing import Any


def localize_tail(checkpoint: str | Path | None = None, scenario: Any = "lab", robots: int = 3,
                  history: int = 10, observe: str = "truth", time_limit: float = 60.0,
                  render_mode: str | None = None) -> Any:
    """The `localize` task's Gymnasium env with a frozen estimator: the ReTLo `checkpoint`
    (from `train retlo`), or the 2X heuristic of §2.6.2.3 when none is given (a default that
    needs no training data; a trained model localizes better)."""
    from estimators.retlo.heuristic import Heuristic2X
    from estimators.retlo.models import TorchPredictor
    from estimators.retlo.online import OnlineChain
    from estimators.retlo.train import load_checkpoint
    from macrostate_mj.chain.scenarios import get_scenario
    from macrostate_mj.core.errors import UserError
    from macrostate_mj.env.gym import TailEnv

    if not (isinstance(time_limit, int | float) and 0 < time_limit < float("inf")):
        raise UserError(f"time_limit must be a positive finite number of seconds, got "
                        f"{time_limit!r}", "time_limit")
    module = (Heuristic2X() if checkpoint is None
              else TorchPredictor(load_checkpoint(checkpoint)[0]))
    steps = int(time_limit * get_scenario(scenario).log_hz) + 2     # every log step, and τ

    def localizer(n: int) -> OnlineChain:
        return OnlineChain(module, n, steps)

    return TailEnv("localize", scenario, robots, history, observe, time_limit, render_mode,
                   localizer=localizer)
