"""`experiment caging-multi`: two cooperating scripted Tails (seed §5.2) against the one Tail of
`experiment caging`, seed by seed, each fed the Head's true position (oracle) or what a ReTLo
estimator believes.

- one_tail: `experiment caging`'s oracle Tail on `CagingTail-v0` (a line of 6 robots);
- two_tails: `tails.caging.SideTails` on the team of `macrostate_mj.env.multi` (6 robots: a Head
  leading chains of 3 and 2), fed the same privileged head source (the Head's true position
  each second): the two Tails take opposite sides of the object once the Head parks at it;
- two_passive: the same two-chain team with both Tails following (offset 0): whether the team
  cages without its Tails acting;
- one_tail_retlo: `experiment caging`'s ReTLo Tail (its three MLPs, trained as that experiment
  trains them and cached the same way);
- two_tails_retlo: `SideTails` fed by the same estimator running live on the shorter chain's
  Tail (fewer modules chained: less lag and less error to add up) from its own observations
  and its chain's share of the team's poses (at τ and every 5 s, as in caging); it tells the
  other Tail where it believes the Head is, as the Tails share the object's centre.
Each arm runs seeds first_seed.. (a seed draws the same start for the Head in both teams); the
cooperative rule was tuned on other seeds (1000 on). Per arm: success rate, time to cage, the
final spacing CV (mean ± std) and, for the estimated arms, the Head estimate's mean error;
paired by seed, two Tails against one (oracle, ReTLo; and the issue's case, the two oracle-fed
scripted Tails against the one ReTLo Tail): who cages, the time differences over seeds both
caged, and their Wilcoxon signed-rank test.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from macrostate_mj.app.experiments import Progress, caging, register
from macrostate_mj.app.params import Count, Positive, Seed, flag
from macrostate_mj.core.cache import run_tasks
from macrostate_mj.core.records import Record
from macrostate_mj.core.stats import mean_std, show, wilcoxon_p

if TYPE_CHECKING:
    from estimators.retlo.mlp import ChainedMLP

ARMS = ("one_tail", "two_tails", "two_passive", "one_tail_retlo", "two_tails_retlo")
TEAMS = ("two_tails", "two_passive", "two_tails_retlo")     # the two-chain team's arms
PAIRS = {"oracle": ("one_tail", "two_tails"), "retlo": ("one_tail_retlo", "two_tails_retlo"),
         "scripted_vs_retlo": ("one_tail_retlo", "two_tails")}       # (one, two)
PRODUCTS = ["results.json"]


@dataclass(frozen=True)
class Config:
    seeds: int = field(default=20, metadata=flag(Count(None, "Episodes per arm.")))
    time_limit: float = field(default=90.0, metadata=flag(Positive(
        None, "Simulated seconds per episode.", max=3600.0)))
    stride: int = 30           # the head source's step in command ticks: 1 Hz, as caging's
    # seeds first_seed .. first_seed + seeds - 1: all that draws
    first_seed: int = field(default=0, metadata=flag(Seed(0, "The first episode's seed (seeds "
                                                          "first..first+seeds-1).")))
    epochs: int = 200          # the ReTLo arms' estimator, as `experiment caging` trains it
    train_steps: int = 800
    rehearsals: int = 40
    seed: int = 0              # its training seed

    def caging(self) -> caging.Config:
        """`experiment caging`'s settings for the same episodes and estimator (so its cached
        estimator is this one's)."""
        return caging.Config(time_limit=self.time_limit, epochs=self.epochs,
                             train_steps=self.train_steps, rehearsals=self.rehearsals,
                             stride=self.stride, seed=self.seed)


PROFILES = {"full": Config(),
            "quick": Config(seeds=2, time_limit=40.0, epochs=20, train_steps=300, rehearsals=2)}


class TeamEstimatorTask(caging.EstimatorTask):
    """`experiment caging`'s estimator, its rehearsals run by the two-chain team (whose Head
    parks at the object, where the line's circles): what its Tails will see."""

    stage: ClassVar[str] = "caging-team-estimator"

    @staticmethod
    def rehearse(runs: int, seconds: float) -> np.ndarray:
        from collectors.caging_runs import team_rehearsal_runs

        return team_rehearsal_runs(runs, seconds)


def team_episode(policy: str, seed: int, cfg: Config, model: ChainedMLP | None = None
                 ) -> dict:
    """One seeded episode of the two-chain team, its Tails scripted (`two_tails`, fed the
    truth; `two_tails_retlo`, fed `model` live) or passive."""
    from estimators.retlo.online import OnlineChain
    from macrostate_mj.chain.caging_mission import cage_report
    from macrostate_mj.env.multi import parallel_env
    from macrostate_mj.tails.caging import LiveHeadSource, SideTails, oracle_source

    env = parallel_env(time_limit=cfg.time_limit)
    obs, infos = env.reset(seed=seed)
    task, agents = env.task, env.possible_agents
    sim = task.sim
    info = infos[agents[0]]
    source, seer, live = oracle_source(sim, cfg.stride), 0, None
    if policy == "two_tails_retlo":
        seer = int(np.argmin([len(b) for b in sim.branches]))
        chain = sim.branches[seer]
        steps = int(cfg.time_limit * sim.cfg.command_hz / cfg.stride) + 2
        live = LiveHeadSource(OnlineChain(model, len(chain), steps), info["team_at_start"],
                              cfg.stride, robots=chain)
        source = live
    tails = SideTails(sim.cfg, sim.k_t, task.caging, float(env.action_space(agents[0]).high[0]),
                      source, seer)
    heads, errors = [], []                # the Head's true track; the estimate's errors
    while env.agents:
        heads.append(sim.poses[0, :2].copy())
        if policy == "two_passive":
            actions = {a: np.zeros(2, np.float32) for a in agents}
        else:
            actions = dict(zip(agents, tails.act([obs[a] for a in agents],
                                                 {**info, "t": sim.time}), strict=True))
        if live is not None and tails.head_estimate is not None:
            at, head = live.latest()
            errors.append(float(np.linalg.norm(head - heads[at])))
        obs, _, _, _, infos = env.step(actions)
        info = infos[agents[0]]
    report = cage_report(sim.poses[task.ring], task.caging)
    env.close()
    return {"policy": policy, "seed": seed, "caged": info["caged_at"] is not None,
            "time_to_cage_s": info["caged_at"], "spacing_cv": report["spacing_cv"],
            "detected_at_s": None if policy == "two_passive" else tails.detected_at,
            "head_estimate_error_m": float(np.mean(errors)) if errors else None,
            "fault": info["fault"]}


def run_episode(policy: str, seed: int, cfg: Config, model: ChainedMLP | None = None) -> dict:
    """One episode of arm `policy` (`model`: the ReTLo arms' estimator)."""
    if policy in ("one_tail", "one_tail_retlo"):
        one = caging.run_episode("oracle" if policy == "one_tail" else "retlo", seed,
                                 cfg.caging(), model)
        return {k: one[k] for k in ("seed", "caged", "time_to_cage_s", "spacing_cv",
                                    "detected_at_s", "head_estimate_error_m", "fault")
                } | {"policy": policy}
    return team_episode(policy, seed, cfg, model)


@dataclass(frozen=True)
class Results(Record):
    """Per arm, the caged share and time to cage, the paired differences between arms over
    seeds both caged, and each episode's record."""

    UNIT = "seed"

    config: dict
    table: dict[str, dict]
    paired: Any
    episodes: list


@register
def run(cfg: Config, out: Path, progress: Progress) -> list[str]:
    """Every arm on every seed; results.json; summary lines."""
    from estimators.retlo.mlp import ChainedMLP

    with progress.stage("train_retlo"):
        tasks = [caging.EstimatorTask(cfg.caging()), TeamEstimatorTask(cfg.caging())]
        trained = {done.task.stage: ChainedMLP.from_npz(done.folder / "mlp.npz")
                   for done in run_tasks(progress.cache, tasks, progress.workers, progress.ray)}
        line, team = (trained[t.stage] for t in tasks)
    seeds = range(cfg.first_seed, cfg.first_seed + cfg.seeds)
    episodes, done = [], 0
    for arm in ARMS:
        with progress.stage(f"episodes_{arm}"):
            for seed in seeds:
                episodes.append(run_episode(arm, seed, cfg, team if arm in TEAMS else line))
                done += 1
                progress.report("episodes", done, len(ARMS) * cfg.seeds)
    by = {a: [e for e in episodes if e["policy"] == a] for a in ARMS}
    table = {a: summary(eps) for a, eps in by.items()}
    paired = {name: paired_comparison(by[one], by[two]) for name, (one, two) in PAIRS.items()}
    Results(asdict(cfg), table, paired, episodes).write(out)
    lines = [f"{a:<15} caged {t['success_rate'] * 100:.0f} % of {t['seeds']} seeds, time "
             f"{show(t['time_to_cage_s'])} s" for a, t in table.items()]
    return [*lines, *(f"{PAIRS[n][1]} - {PAIRS[n][0]} over {p['both_caged']} seeds both caged: "
                      f"{show(p['time_difference_s'])} s, Wilcoxon p = {p['wilcoxon_p']}"
                      for n, p in paired.items())]


def summary(eps: list[dict]) -> dict:
    caged = [e for e in eps if e["caged"]]
    return {"seeds": len(eps), "success_rate": len(caged) / len(eps),
            "time_to_cage_s": mean_std([e["time_to_cage_s"] for e in caged]),
            "spacing_cv": mean_std([e["spacing_cv"] for e in caged]),
            "head_estimate_error_m": mean_std([e["head_estimate_error_m"] for e in eps
                                               if e["head_estimate_error_m"] is not None]),
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
