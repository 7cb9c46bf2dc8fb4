"""`experiment caging-multi`: two cooperating scripted Tails (seed §5.2) against the one Tail of
`experiment caging`, seed by seed.

- one_tail: `experiment caging`'s oracle Tail on `CagingTail-v0` (a line of 6 robots);
- two_tails: `chain.team.SideTails` on the team of `macrostate_mj.env.multi` (6 robots: a Head
  leading chains of 3 and 2), fed the same privileged head source (the Head's true position
  each second): the two Tails take opposite sides of the object once the Head parks at it;
- two_passive: the same two-chain team with both Tails following (offset 0): whether the team
  cages without its Tails acting.
Each arm runs seeds 0..seeds-1 (a seed draws the same start for the Head in both teams); the
cooperative rule was tuned on other seeds (1000 on). Per arm: success rate, time to cage and
the final spacing CV (mean ± std); paired by seed, two_tails against one_tail: who cages, the
time differences over seeds both caged, and their Wilcoxon signed-rank test.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from macrostate_mj.app.experiments import Progress, mean_std, show, wilcoxon_p
from macrostate_mj.core.io import write_json_atomic

ARMS = ("one_tail", "two_tails", "two_passive")
PRODUCTS = ["results.json"]


@dataclass(frozen=True)
class Config:
    seeds: int = 20
    time_limit: float = 90.0
    stride: int = 30           # the head source's step in command ticks: 1 Hz, as caging's
    first_seed: int = 0        # seeds first_seed .. first_seed + seeds - 1: all that draws


PROFILES = {"full": Config(), "quick": Config(seeds=2, time_limit=40.0)}


def team_episode(policy: str, seed: int, cfg: Config) -> dict:
    """One seeded episode of the two-chain team, its Tails scripted (`two_tails`) or passive."""
    from macrostate_mj.chain.caging import cage_report, oracle_source
    from macrostate_mj.chain.team import SideTails
    from macrostate_mj.env.multi import parallel_env

    env = parallel_env(time_limit=cfg.time_limit)
    obs, infos = env.reset(seed=seed)
    task, agents = env.task, env.possible_agents
    sim = task.sim
    tails = SideTails(sim.cfg, sim.k_t, task.caging, float(env.action_space(agents[0]).high[0]),
                      oracle_source(sim, cfg.stride))
    info = infos[agents[0]]
    while env.agents:
        if policy == "two_tails":
            actions = dict(zip(agents, tails.act([obs[a] for a in agents], info, sim.time),
                               strict=True))
        else:
            actions = {a: np.zeros(2, np.float32) for a in agents}
        obs, _, _, _, infos = env.step(actions)
        info = infos[agents[0]]
    report = cage_report(sim.poses[task.ring], task.caging)
    env.close()
    return {"policy": policy, "seed": seed, "caged": info["caged_at"] is not None,
            "time_to_cage_s": info["caged_at"], "spacing_cv": report["spacing_cv"],
            "detected_at_s": tails.detected_at if policy == "two_tails" else None,
            "fault": info["fault"]}


def run_episode(policy: str, seed: int, cfg: Config) -> dict:
    """One episode of arm `policy`."""
    if policy == "one_tail":
        from macrostate_mj.app.experiments import caging

        one = caging.run_episode("oracle", seed, caging.Config(time_limit=cfg.time_limit,
                                                               stride=cfg.stride))
        return {k: one[k] for k in ("seed", "caged", "time_to_cage_s", "spacing_cv",
                                    "detected_at_s", "fault")} | {"policy": policy}
    return team_episode(policy, seed, cfg)


def run(cfg: Config, out: Path, progress: Progress) -> list[str]:
    """Every arm on every seed; results.json; summary lines."""
    seeds = range(cfg.first_seed, cfg.first_seed + cfg.seeds)
    episodes, done = [], 0
    for arm in ARMS:
        with progress.stage(f"episodes_{arm}"):
            for seed in seeds:
                episodes.append(run_episode(arm, seed, cfg))
                done += 1
                progress.report("episodes", done, len(ARMS) * cfg.seeds)
    by = {a: [e for e in episodes if e["policy"] == a] for a in ARMS}
    table = {a: summary(eps) for a, eps in by.items()}
    paired = paired_comparison(by["one_tail"], by["two_tails"])
    write_json_atomic(out / "results.json", {"config": asdict(cfg), "table": table,
                                             "paired": paired, "episodes": episodes})
    lines = [f"{a:<11} caged {t['success_rate'] * 100:.0f} % of {t['seeds']} seeds, time "
             f"{show(t['time_to_cage_s'])} s" for a, t in table.items()]
    return [*lines, f"two_tails - one_tail over {paired['both_caged']} seeds both caged: "
            f"{show(paired['time_difference_s'])} s, Wilcoxon p = {paired['wilcoxon_p']}"]


def summary(eps: list[dict]) -> dict:
    caged = [e for e in eps if e["caged"]]
    return {"seeds": len(eps), "success_rate": len(caged) / len(eps),
            "time_to_cage_s": mean_std([e["time_to_cage_s"] for e in caged]),
            "spacing_cv": mean_std([e["spacing_cv"] for e in caged]),
            "faults": sum(e["fault"] is not None for e in eps)}


def paired_comparison(one: list[dict], two: list[dict]) -> dict:
    """Seed by seed: who cages (counts), and over seeds both caged the time differences
    (two - one, s) with the Wilcoxon signed-rank test (two-sided; None under 2 pairs or when
    every difference is 0); `two_faster` counts the seeds two_tails caged sooner."""
    pairs = [(a, b) for a, b in zip(one, two, strict=True) if a["seed"] == b["seed"]]
    both = [(a["time_to_cage_s"], b["time_to_cage_s"]) for a, b in pairs
            if a["caged"] and b["caged"]]
    diff = [b - a for a, b in both]
    return {"seeds": len(pairs), "both_caged": len(both),
            "only_one_tail": sum(a["caged"] and not b["caged"] for a, b in pairs),
            "only_two_tails": sum(b["caged"] and not a["caged"] for a, b in pairs),
            "neither": sum(not (a["caged"] or b["caged"]) for a, b in pairs),
            "time_difference_s": mean_std(diff), "two_faster": sum(d < 0 for d in diff),
            "wilcoxon_p": wilcoxon_p(diff)}
