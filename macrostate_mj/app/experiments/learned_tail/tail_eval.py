"""Tails on `LocalizeTail-v0`, one seeded episode each, scored by what the frozen estimator
makes of the team (for `experiment learned-tail`): every Tail (`macrostate_mj.tails`: passive,
Rand-Only, SRS-Med, the scripted chain-offset Tail, the learned one) acts through the Gymnasium
API only, so the learned policy and the baselines meet the same environment. The chain-offset
Tail's offset is the one of a small grid with the lowest mean Head error on tuning seeds
(`tune_chain_offset`), held out from the evaluation seeds.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from macrostate_mj.core.errors import UserError
from macrostate_mj.core.stats import wilcoxon_p
from macrostate_mj.env.estimated import ID as ENV_ID
from macrostate_mj.tails import Tail
from macrostate_mj.tails.scripted import ChainOffset


def make_env(checkpoint: str | None, time_limit: float) -> Any:
    import gymnasium

    import macrostate_mj  # noqa: F401  (registers the ids)

    return gymnasium.make(ENV_ID, checkpoint=checkpoint, time_limit=time_limit)


def run_episode(make_tail: Callable[[Any], Tail], seed: int, checkpoint: str | None,
                time_limit: float, record: bool = False) -> dict:
    """One episode from `seed` with the Tail `make_tail(env)` makes: the estimator's mean Head
    error (m) over the steps with an estimate, its mean error over every robot it estimates
    (F2 .. Head), the mean neighbour spacing (m), and whether a chain break (or a fault) ended
    it. With `record`, also "truth" (log steps, robots, 3) and "estimate" (log steps, robots,
    2), Tail first, for a video."""
    from macrostate_mj.chain.sim import chain_broken

    env = make_env(checkpoint, time_limit)
    obs, info = env.reset(seed=seed)
    tail = make_tail(env)
    task = env.unwrapped.task
    sim = task.sim
    poses, spacings, errors, ret, steps = [sim.poses[::-1].copy()], [], [], 0.0, 0
    terminated = truncated = False
    while not (terminated or truncated):
        obs, reward, terminated, truncated, info = env.step(
            tail.act(obs, {**info, "t": sim.time}))
        ret += float(reward)
        steps += 1
        if len(task.truth) > len(poses):            # a log tick: the estimator stepped
            poses.append(sim.poses[::-1].copy())
        if info["head_error_m"] is not None:
            errors.append(info["head_error_m"])
        spacings.append(float(np.mean(np.linalg.norm(np.diff(sim.poses[:, :2], axis=0),
                                                     axis=1))))
    broken = bool(terminated and info.get("fault") is None and chain_broken(sim))
    truth = np.asarray(poses)
    est = np.array(task.localizer.pos[:len(truth)])
    diff = np.linalg.norm(est[1:, 2:] - truth[1:, 2:, :2], axis=-1)
    env.close()
    return {"seed": seed, "head_error_m": float(np.mean(errors)) if errors else None,
            "all_error_m": float(np.nanmean(diff)) if np.isfinite(diff).any() else None,
            "spacing_m": float(np.mean(spacings)), "broken": broken,
            "fault": info.get("fault"), "steps": steps, "return": ret,
            **({"truth": truth, "estimate": est} if record else {})}


def tune_chain_offset(grid: Sequence[tuple[float, float]], seeds: Sequence[int],
                      checkpoint: str | None, time_limit: float) -> dict:
    """Each (along, left) of `grid` on the tuning `seeds`; the pick: the lowest mean Head error
    among those that never broke the chain (the scripted Tail must not win by ending early)."""
    rows = []
    for along, left in grid:
        tail = ChainOffset(along, left)
        eps = [run_episode(lambda _, t=tail: t, s, checkpoint, time_limit) for s in seeds]
        errs = [e["head_error_m"] for e in eps if e["head_error_m"] is not None]
        rows.append({"along": along, "left": left, "breaks": sum(e["broken"] for e in eps),
                     "head_error_m": float(np.mean(errs)) if errs else float("inf")})
    whole = [r for r in rows if r["breaks"] == 0] or rows
    best = min(whole, key=lambda r: r["head_error_m"])
    return {"grid": rows, "along": best["along"], "left": best["left"], "seeds": list(seeds)}


def paired_vs(base: list[dict], other: list[dict], key: str = "head_error_m") -> dict:
    """Seed by seed, other - base: mean difference and the Wilcoxon signed-rank test
    (two-sided; None under 2 pairs or when every difference is 0)."""
    by = {e["seed"]: e[key] for e in base}
    diff = [e[key] - by[e["seed"]] for e in other
            if e[key] is not None and by.get(e["seed"]) is not None]
    if not diff:
        return {"pairs": 0, "mean_difference": None, "better": 0, "wilcoxon_p": None}
    return {"pairs": len(diff), "mean_difference": float(np.mean(diff)),
            "better": sum(d < 0 for d in diff), "wilcoxon_p": wilcoxon_p(diff)}


def check_seeds(eval_seeds: int, tune_first: int, train_first: int) -> None:
    """Evaluation seeds 0..eval_seeds-1 must stay below every tuning and training seed."""
    if eval_seeds > tune_first or eval_seeds > train_first:
        raise UserError(f"seeds must be at most {min(tune_first, train_first)}: evaluation "
                        "seeds 0..seeds-1 must not overlap the tuning and training seeds",
                        "seeds")
