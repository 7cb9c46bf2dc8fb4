"""Environments that carry an estimator (`env` sits above `estimators` for them): what the
`LocalizeTail-v0` id makes, and the estimator it carries unless told otherwise."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from macrostate_mj.core.paths import MODELS
from macrostate_mj.gym_ids import ENVS

ID = "macrostate_mj/LocalizeTail-v0"
ID_DEFAULTS = ENVS[ID]        # its scenario and team size: set once, where the id is registered

# The default: a Gaussian FC ReTLo module trained on a passive `webots` 3-robot collection (the
# id's scenario); how it was made and what it scores: macrostate_mj/assets/models/README.md.
DEFAULT_CHECKPOINT = MODELS / "webots3_fc_gaussian.pt"
HEURISTIC = "heuristic2x"     # the 2X heuristic of §2.6.2.3, named where a checkpoint may go


def load_estimator(checkpoint: str | Path | None = None) -> Any:
    """The ReTLo module of `checkpoint` (from `train retlo`; `HEURISTIC`: the 2X heuristic),
    or of `DEFAULT_CHECKPOINT`."""
    from estimators.retlo.heuristic import Heuristic2X
    from estimators.retlo.models import TorchPredictor
    from estimators.retlo.train import load_checkpoint

    if checkpoint == HEURISTIC:
        return Heuristic2X()
    return TorchPredictor(load_checkpoint(checkpoint or DEFAULT_CHECKPOINT)[0])


def localize_tail(checkpoint: str | Path | None = None, scenario: Any = ID_DEFAULTS["scenario"],
                  robots: int = ID_DEFAULTS["robots"], history: int = 10, observe: str = "truth",
                  time_limit: float = 60.0, render_mode: str | None = None,
                  estimator: Any = None) -> Any:
    """The `localize` task's Gymnasium env with a frozen estimator: the ReTLo `checkpoint`
    (from `train retlo`, or "heuristic2x"; default `DEFAULT_CHECKPOINT`), or `estimator`, any
    ReTLo module object."""
    from estimators.retlo.online import OnlineChain
    from macrostate_mj.chain.scenarios import scenario_for
    from macrostate_mj.core.errors import UserError
    from macrostate_mj.env.gym import TailEnv

    if not (isinstance(time_limit, int | float) and 0 < time_limit < float("inf")):
        raise UserError(f"time_limit must be a positive finite number of seconds, got "
                        f"{time_limit!r}", "time_limit")
    if isinstance(robots, int) and not isinstance(robots, bool) and robots < 3:
        raise UserError(f"the localize task estimates a chain of a Tail, a Follower and a Head: "
                        f"robots must be at least 3, got {robots}", "robots")
    if checkpoint is not None and estimator is not None:
        raise UserError("pass a checkpoint or an estimator, not both", "estimator")
    module = estimator if estimator is not None else load_estimator(checkpoint)
    cfg = scenario_for(scenario)           # resolved here, once: the env below takes the config
    steps = int(time_limit * cfg.log_hz) + 2     # every log step, and τ

    def localizer(n: int) -> OnlineChain:
        return OnlineChain(module, n, steps)

    return TailEnv("localize", cfg, robots, history, observe, time_limit, render_mode,
                   localizer=localizer)
