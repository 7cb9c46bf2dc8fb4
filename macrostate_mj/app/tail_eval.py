"""Scripted and learned Tails on `LocalizeTail-v0`, one seeded episode each, scored by what the
frozen estimator makes of the team (for `experiment learned-tail`).

Every Tail acts through the Gymnasium API only (the action: the destination offset SRS
perturbs), so the learned policy and the baselines meet the same environment:

- passive: offset 0 (the chain's own rule);
- random: Rand-Only (§3.3): N(0, (σ · robot size)² I) each log step in random mode, alternating
  with passive mode every `alternate` steps, as `collectors.policies.TailPolicy` draws it;
- srs_med: SRS-Med's Tail (§3.3.1; the novelty models trained on a Rand-Only collection of the
  scenario), reading the team's true poses as the SR phase does;
- chain_offset: the scripted heuristic: a fixed offset in the chain's frame (along the Tail ->
  neighbour direction and to its left), the one of a small grid with the lowest mean Head error
  on tuning seeds (`tune_chain_offset`), held out from the evaluation seeds;
- learned: a PPO policy's deterministic action, through the spacing shield it trained with.

The spacing shield (`shield`): when the Tail sees its neighbour farther than a limit, its
action becomes passive (offset 0: the chain's own rule closes the gap) until the gap is back
under it. It uses only what the Tail observes, and keeps a policy from ending an episode with a
chain break (`env.explore.BREAK_SPACINGS`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, Protocol

import numpy as np

from macrostate_mj.app.envs import ID as ENV_ID
from macrostate_mj.core.errors import UserError
from macrostate_mj.core.stats import wilcoxon_p


class Tail(Protocol):
    """A Tail for one episode: `act` maps the observation to a destination offset (m)."""

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray: ...


class Passive:
    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        return np.zeros(2, np.float32)


class RandOnly:
    """Rand-Only's draw, clipped to the action bounds (σ · size is well inside them)."""

    def __init__(self, rng: np.random.Generator, sigma: float, bound: float, alternate: int = 6):
        self.rng, self.sigma, self.bound, self.alternate = rng, sigma, bound, alternate
        self.step = 0

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        from macrostate_mj.chain.motion import draw_tail_offsets

        random_mode = (self.step // self.alternate) % 2 == 0
        self.step += 1
        if not random_mode:
            return np.zeros(2, np.float32)
        return np.clip(draw_tail_offsets(self.rng, self.sigma), -self.bound,
                       self.bound).astype(np.float32)


class ChainOffset:
    """The offset `along` (m, toward the neighbour) and `left` (m, to its left) in the frame of
    the Tail -> neighbour direction at the latest observation: it holds the neighbour at one
    bearing and distance from the Tail, whichever way the Head leads."""

    def __init__(self, along: float, left: float):
        self.along, self.left = along, left

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        d = obs["neighbour"][-1, :2] - obs["tail"][-1, :2]
        u = d / max(float(np.linalg.norm(d)), 1e-9)
        return (self.along * u + self.left * np.array([-u[1], u[0]])).astype(np.float32)


class SRSTail:
    """SRS's Tail (§3.3.1) with a pick policy (SRS-Med: the median novelty), its SR phase's
    choice each log step, held between them. Like the SR phase that collects data, it reads the
    whole team's true poses (`policy` scores candidates by what the Head and Follower would
    do): privileged, where the other Tails see only their neighbour."""

    def __init__(self, env: Any, policy: Any, bound: float):
        task = env.unwrapped.task
        self.sim, self.every, self.policy, self.bound = task.sim, task.every, policy, bound
        self.step = 0
        self.offset = np.zeros(2, np.float32)

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        if self.step % self.every == 0:
            self.offset = np.clip(self.policy.choose(self.sim), -self.bound,
                                  self.bound).astype(np.float32)
        self.step += 1
        return self.offset


def shield(obs: dict[str, np.ndarray], action: np.ndarray, limit_m: float | None
           ) -> np.ndarray:
    """`action`, or offset 0 (passive) when the Tail's neighbour is farther than `limit_m`
    (None: no shield)."""
    if limit_m is None:
        return action
    gap = float(np.linalg.norm(obs["neighbour"][-1, :2] - obs["tail"][-1, :2]))
    return np.zeros_like(action) if gap > limit_m else action


def shield_limit(env: Any, spacings: float | None) -> float | None:
    """The shield's gap limit (m): `spacings` × the env's chain spacing; None: no shield."""
    return None if spacings is None else spacings * env.unwrapped.task.sim.cfg.spacing


class Learned:
    """A stable-baselines3 policy, deterministic at evaluation, behind its spacing shield."""

    def __init__(self, model: Any, limit_m: float | None = None):
        self.model, self.limit_m = model, limit_m

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        return shield(obs, self.model.predict(obs, deterministic=True)[0], self.limit_m)


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
    from macrostate_mj.env.explore import chain_broken

    env = make_env(checkpoint, time_limit)
    obs, _ = env.reset(seed=seed)
    tail = make_tail(env)
    task = env.unwrapped.task
    sim = task.sim
    poses, spacings, errors, ret, steps = [sim.poses[::-1].copy()], [], [], 0.0, 0
    info: dict = {}
    terminated = truncated = False
    while not (terminated or truncated):
        obs, reward, terminated, truncated, info = env.step(tail.act(obs))
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
