"""`experiment learned-tail`: a Tail that learns its own motion to help its estimator (seed
§5.2) on `LocalizeTail-v0`, against scripted Tails, through the Gymnasium API only.

PPO (stable-baselines3, the `rl` extra; `MultiInputPolicy` on the Tail's and its neighbour's
pose histories and the latest Head estimate with its covariance) learns the destination offset
that SRS perturbs, rewarded by minus the frozen estimator's Head error (m) each step (the env's
default ReTLo module, `env.estimated.DEFAULT_CHECKPOINT`, or a `train retlo` checkpoint), on
training seeds from 1000 up. A chain break costs the steps it cut short, and the policy acts
through a spacing shield, passive while its neighbour is over 2 d away (`tails.ppo`). Then every
Tail runs the held-out seeds 0..seeds-1 (`tail_eval`): passive, Rand-Only (σ = 75 % of the
robot size), SRS-Med (its novelty models trained on the RO phase of an SRS collection of the
env's scenario, seeds 700 on), the scripted chain-offset Tail (tuned on seeds 500 up) and the
learned one. Per Tail: the estimator's mean Head error over the episode and over every robot
it estimates (mean ± std over seeds), the Wilcoxon signed-rank test against passive paired by
seed, the mean neighbour spacing, and the episodes a chain break ended.
"""

from __future__ import annotations

import hashlib
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from macrostate_mj.app.experiments import Parallel, Progress, register
from macrostate_mj.app.params import Choice, Count, InputFileOr, Positive, Seed, flag
from macrostate_mj.app.results.sources import (
    record,
    source,
    stat,
)
from macrostate_mj.core.errors import UserError
from macrostate_mj.core.evidence import Table
from macrostate_mj.core.records import Record
from macrostate_mj.core.stats import mean_std, show
from macrostate_mj.env.estimated import HEURISTIC

POLICIES = ("passive", "random", "srs_med", "chain_offset", "learned")
PRODUCTS = ["results.json", "learning_curve.png", "episodes"]
TUNE_SEEDS = 500          # the scripted Tail's tuning seeds start here (evaluation: 0..seeds-1)
GRID = tuple((a, b) for a in (-0.1, 0.0, 0.1) for b in (-0.1, 0.0, 0.1))    # (along, left) m
CHECKPOINTS = "checkpoints"
SRS = "srs"               # SRS-Med's collection: its RO phase trains the novelty models
SRS_SEED = 700            # that collection's seed: its own stream, apart from every episode seed


@dataclass(frozen=True)
class Config:
    # 240 rollouts: ~35 min at ~115 steps/s on one core here
    timesteps: int = field(default=245_760, metadata=flag(Count(None, "PPO timesteps.")))
    envs: int = 4                   # vector environments (what the rollouts hold)
    n_steps: int = 256              # per environment per rollout
    batch_size: int = 128
    save_every: int = 10_240
    seeds: int = field(default=20, metadata=flag(Count(
        None, "Evaluation episodes per Tail (seeds 0..seeds-1, held out from training).",
        max=500)))
    tune_seeds: int = 4
    time_limit: float = field(default=60.0, metadata=flag(Positive(
        None, "Simulated seconds per episode.", max=3600.0)))
    sigma: float = 0.75             # Rand-Only's σ, a fraction of the robot size (and SRS's)
    srs_ro_instances: int = 100     # SRS's RO phase, 3 robots of the env's scenario (§3.5)
    srs_k: int = 30                 # SRS's candidates per step
    checkpoint: str | None = field(default=None, metadata=flag(InputFileOr(
        None, "The Tail's frozen estimator: a ReTLo checkpoint from `train retlo`, or "
        "heuristic2x.", (HEURISTIC,), (".pt",)), shown="the env's trained one, in "
        "macrostate_mj/assets/models"))
    policies: tuple[str, ...] = field(default=POLICIES, metadata=flag(Choice(
        None, "Evaluate only this Tail (repeatable; passive always runs, the baseline of the "
        "paired test).", POLICIES, "--policy"), parse=lambda chosen: (
            "passive", *sorted(set(chosen) - {"passive"}, key=POLICIES.index))))
    seed: int = field(default=0, metadata=flag(Seed(0, "Seed of the PPO training and the "
                                                    "random Tail's draws.")))

    def __post_init__(self) -> None:
        for name in ("timesteps", "envs", "n_steps", "batch_size", "save_every", "seeds",
                     "tune_seeds", "srs_ro_instances", "srs_k"):
            value = getattr(self, name)
            if not isinstance(value, int) or value < 1:
                raise UserError(f"{name} must be a positive whole number, got {value!r}", name)
        if not 0 < self.time_limit < float("inf"):
            raise UserError(f"time_limit must be positive, got {self.time_limit!r}",
                            "time_limit")
        unknown = sorted(set(self.policies) - set(POLICIES))
        if unknown or "passive" not in self.policies:
            raise UserError(f"policies must include passive and name only "
                            f"{', '.join(POLICIES)}; got {', '.join(self.policies)}", "policies")
        if self.seeds > TUNE_SEEDS:
            raise UserError(f"seeds must be at most {TUNE_SEEDS}: evaluation seeds 0..seeds-1 "
                            "stay below the tuning and training seeds", "seeds")

    def ppo(self) -> object:
        from macrostate_mj.tails.ppo import PPOSpec

        return PPOSpec(self.timesteps, self.envs, self.n_steps, self.batch_size,
                       save_every=self.save_every, time_limit=self.time_limit, seed=self.seed)


PARALLEL = Parallel("the vector environments' processes; 1: all in this one", ray=False)
PROFILES = {"full": Config(),
            "quick": Config(timesteps=512, envs=2, n_steps=128, batch_size=64, save_every=256,
                            seeds=2, tune_seeds=1, time_limit=20.0, srs_ro_instances=3,
                            srs_k=4)}


def missing(cfg: Config) -> str | None:
    """What `experiment all` lacks to run this: the `rl` extra."""
    import importlib.util

    if importlib.util.find_spec("stable_baselines3") is None:
        return "stable-baselines3 (the `rl` extra)"
    return None


def check_checkpoint(cfg: Config) -> None:
    """Refuse a bad estimator checkpoint before training (one line)."""
    if cfg.checkpoint not in (None, HEURISTIC):
        from estimators.retlo.train import load_checkpoint

        try:
            load_checkpoint(cfg.checkpoint)
        except UserError as err:
            raise UserError(str(err), "checkpoint") from None


@dataclass(frozen=True)
class Results(Record):
    """Per Tail, its evaluation over seeded episodes (paired against passive), the PPO
    training's account and the scripted Tails' tuning."""

    UNIT = "seed"

    config: dict
    ppo: dict
    training: dict
    table: dict[str, dict]
    episodes: Any
    chain_offset: Any
    srs_novelty: Any
    estimator_sha256: str


@register
def run(cfg: Config, out: Path, progress: Progress) -> list[str]:
    """Train (or resume) the policy, tune the scripted Tail, evaluate every Tail; results.json,
    learning_curve.png; summary lines."""
    from macrostate_mj.app.experiments.learned_tail import tail_eval
    from macrostate_mj.env.estimated import DEFAULT_CHECKPOINT
    from macrostate_mj.tails import ppo
    from viz.learned_tail_figures import plot_learning_curve

    check_checkpoint(cfg)
    cfg = replace(cfg, checkpoint=cfg.checkpoint or str(DEFAULT_CHECKPOINT))
    spec = cfg.ppo()
    model, training = None, {"steps": 0, "curve": [], "resumed_from": 0, "steps_run_now": 0}
    if "learned" in cfg.policies:
        ppo.require_sb3()
        with progress.stage("train_ppo"):
            t0 = time.perf_counter()
            folder = ppo.folder_for(out / CHECKPOINTS, spec, estimator_inputs(cfg.checkpoint))
            model, training = ppo.train(spec, cfg.checkpoint, folder, progress.workers,
                                        lambda d, t: progress.report("timesteps", d, t))
            wall = time.perf_counter() - t0
            training |= {"wall_s": round(wall, 1), "folder": str(folder.relative_to(out)),
                         "steps_per_s": (round(training["steps_run_now"] / wall, 1)
                                         if training["steps_run_now"] else None)}
        progress.record(ppo_steps=training["steps"], resumed_from=training["resumed_from"],
                        steps_run_now=training["steps_run_now"])
    tuned = None
    if "chain_offset" in cfg.policies:
        with progress.stage("tune_chain_offset"):
            tuned = tail_eval.tune_chain_offset(
                GRID, range(TUNE_SEEDS, TUNE_SEEDS + cfg.tune_seeds), cfg.checkpoint,
                cfg.time_limit)
    novelty = None
    if "srs_med" in cfg.policies:
        with progress.stage("srs_novelty_models"):
            novelty = srs_models(cfg, out / SRS, progress.workers)
    episodes = _evaluate(cfg, model, tuned, novelty, progress, out / PRODUCTS[2])
    by = {p: [e for e in episodes if e["policy"] == p] for p in cfg.policies}
    table = {p: _summary(eps, by["passive"]) for p, eps in by.items()}
    results = {"config": asdict(cfg), "ppo": asdict(spec), "training": training,
               "estimator_sha256": None if cfg.checkpoint == HEURISTIC else
               hashlib.sha256(Path(cfg.checkpoint).read_bytes()).hexdigest(),
               "chain_offset": tuned, "table": table, "episodes": episodes,
               "srs_novelty": None if novelty is None else asdict(novelty)}
    Results.of(results, "experiment learned-tail").write(out)
    plot_learning_curve(training["curve"], float(np.mean([e["return"] for e in by["passive"]])),
                        out / "learning_curve.png")
    lines = [f"{p:<12} Head error {show(t['head_error_m'], 3)} m, vs passive p = "
             f"{_p(t['vs_passive']['wilcoxon_p'])}, spacing {show(t['spacing_m'], 3)} m, breaks "
             f"{t['breaks']}/{t['seeds']}" for p, t in table.items()]
    return [*lines, f"PPO: {training['steps']} steps ({training['steps_run_now']} run now)"]


def estimator_inputs(checkpoint: str | None) -> list:
    """The frozen estimator as the policy folder's key reads it: a checkpoint by its bytes,
    the 2X heuristic by its name, the env's default by nothing."""
    return [] if checkpoint is None else [HEURISTIC.encode()] if checkpoint == HEURISTIC \
        else [checkpoint]


def srs_models(cfg: Config, out: Path, workers: int) -> Any:
    """SRS-Med's novelty models: an SRS collection of 3 robots in the env's scenario (seed
    `SRS_SEED`), its RO phase of `srs_ro_instances` instances at σ, then the one SR instance
    the collection needs (`collectors.srs_collection`; cached, resumed); the stored models'
    source."""
    from collectors.runner import CollectRequest
    from collectors.srs_collection import NOVELTY, SRSRequest, collect_srs, finished_srs
    from estimators.srs.novelty import NoveltyTraining
    from macrostate_mj.env.estimated import ID_DEFAULTS

    base = CollectRequest(ID_DEFAULTS["scenario"], 3, 0.0, SRS_SEED, out,
                          "random", cfg.sigma, workers, overwrite=True)
    req = SRSRequest(base, "med", cfg.srs_ro_instances + 1, cfg.srs_ro_instances, cfg.srs_k)
    novelty = NoveltyTraining()
    if not finished_srs(req, novelty):
        collect_srs(req, novelty)
    path = (out / NOVELTY).resolve()
    return novelty.source(path, hashlib.sha256(path.read_bytes()).hexdigest())


def _evaluate(cfg: Config, model: object, tuned: dict | None, novelty: Any,
              progress: Progress, videos: Path) -> list[dict]:
    """Every Tail on every evaluation seed; seed 0's episode of each also as a video with the
    estimates drawn (`videos/<policy>_seed0.mp4`)."""
    from macrostate_mj.app.experiments.learned_tail import tail_eval
    from macrostate_mj.tails import Tail
    from macrostate_mj.tails.learned import Learned, shield_limit
    from macrostate_mj.tails.scripted import ChainOffset, Passive, RandOnly
    from viz.learned_tail_figures import write_episode_video

    def tail_for(policy: str, seed: int) -> Callable[[Any], Tail]:
        if policy == "passive":
            return lambda env: Passive()
        if policy == "random":
            rng = np.random.default_rng([cfg.seed, seed, 11])
            return lambda env: RandOnly(rng, cfg.sigma, float(env.action_space.high[0]))
        if policy == "srs_med":
            from macrostate_mj.tails.srs import SRSConfig, SRSTail

            srs = SRSConfig(novelty, "med", cfg.srs_k, cfg.sigma)
            rng = np.random.default_rng([cfg.seed, seed, 13])
            return lambda env: SRSTail(env.unwrapped.task.sim, env.unwrapped.task.every,
                                       srs.build(rng), float(env.action_space.high[0]))
        if policy == "chain_offset" and tuned is not None:
            return lambda env: ChainOffset(tuned["along"], tuned["left"])
        spacings = cfg.ppo().shield_spacings
        return lambda env: Learned(model, shield_limit(env, spacings))

    episodes, done = [], 0
    for policy in cfg.policies:
        with progress.stage(f"episodes_{policy}"):
            for seed in range(cfg.seeds):
                ep = tail_eval.run_episode(tail_for(policy, seed), seed, cfg.checkpoint,
                                           cfg.time_limit, record=seed == 0)
                if seed == 0:
                    videos.mkdir(exist_ok=True)
                    write_episode_video(videos / f"{policy}_seed0.mp4", ep.pop("truth"),
                                        ep.pop("estimate"), "2X heuristic"
                                        if cfg.checkpoint == HEURISTIC else "ReTLo")
                episodes.append({"policy": policy, **ep})
                done += 1
                progress.report("episodes", done, len(cfg.policies) * cfg.seeds)
    return episodes


def _summary(eps: list[dict], passive: list[dict]) -> dict:
    from macrostate_mj.app.experiments.learned_tail.tail_eval import paired_vs

    return {"seeds": len(eps), "head_error_m": mean_std([e["head_error_m"] for e in eps]),
            "all_error_m": mean_std([e["all_error_m"] for e in eps]),
            "spacing_m": mean_std([e["spacing_m"] for e in eps]),
            "breaks": sum(e["broken"] for e in eps),
            "faults": sum(e["fault"] is not None for e in eps),
            "vs_passive": paired_vs(passive, eps)}


def _p(p: float | None) -> str:
    return "-" if p is None else f"{p:.3g}"


# Its tables and numbers as the docs show them ----------------------------------------

@source
def learned_tail(folder: str) -> Table:
    """Each Tail's frozen-estimator error (cm) on held-out seeds, its paired test against the
    Passive Tail, the chain's spacing and its breaks."""
    table = record(Results, folder).table
    rows = [["Tail", "Head error (cm)", "all robots (cm)", "p vs passive", "better seeds",
             "spacing (cm)", "breaks"]]
    for tail, arm in table.items():
        test = arm.get("vs_passive") or {}
        if test.get("wilcoxon_p") is None:      # the Passive Tail against itself
            test = {}
        rows.append([tail, stat(arm["head_error_m"], ".1f", 100),
                     stat(arm["all_error_m"], ".1f", 100),
                     f"{test['wilcoxon_p']:.2g}" if test else "",
                     f"{test['better']} / {test['pairs']}" if test else "",
                     f"{arm['spacing_m']['mean'] * 100:.1f}", f"{arm['breaks']} / {arm['seeds']}"])
    return rows


@source
def learned_tail_seeds(*folders: str) -> Table:
    """The learned Tail of each PPO training seed (one `experiment learned-tail --seed` run
    per folder) on the same held-out seeds: its Head error, the paired test against Passive,
    its breaks."""
    rows = [["PPO seed", "Head error (cm)", "Passive (cm)", "p vs passive", "better seeds",
             "breaks"]]
    for folder in folders:
        data = record(Results, folder)
        table = data.table
        learned, test = table["learned"], table["learned"]["vs_passive"]
        rows.append([str(data.config["seed"]), stat(learned["head_error_m"], ".1f", 100),
                     stat(table["passive"]["head_error_m"], ".1f", 100),
                     f"{test['wilcoxon_p']:.2g}", f"{test['better']} / {test['pairs']}",
                     f"{learned['breaks']} / {learned['seeds']}"])
    return rows

