"""`macrostate-mj collect`: episodes in parallel (local processes or Ray), shards, datasets.

Each finished episode is stored as `shards/episode_NNNNN.parquet`, written atomically by the
driver as results arrive; a rerun of the same command after a kill skips the shards present,
and no partial shard can exist. The datasets are assembled from the shards in episode order,
so the CSVs are bit-identical whatever the number of workers or the executor.
"""

from __future__ import annotations

import json
import math
import shutil
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from collectors.episodes import EpisodeSpec, run_episode
from collectors.policies import PolicyConfig, PolicySpec
from collectors.randomize import Randomization
from macrostate_mj.chain.scenarios import scenario_for
from macrostate_mj.chain.world import validate_chain
from macrostate_mj.core.errors import RunFailure, UserError
from macrostate_mj.core.io import atomic_path, prepare_out_dir, write_manifest, write_text_atomic
from macrostate_mj.core.parallel import runner_for
from macrostate_mj.formats.instances import (
    INSTANCE_STEPS,
    cut_instances,
    instance_starts,
    split_indices,
    to_thymioloc_pixels,
)
from macrostate_mj.formats.poses import table_arrays, write_poses
from macrostate_mj.formats.thymioloc import DEFAULT_PX_PER_CM, write_csv

SPLIT_NAMES = ("Train", "Val", "Test")
PRODUCTS = ["instances.csv", "instances_truth.csv", "poses.parquet", "manifest.json",
            "decisions.parquet",
            *(f"{s}{t}.csv" for s in SPLIT_NAMES for t in ("", "_truth"))]


@dataclass(frozen=True)
class CollectRequest:
    scenario: str
    robots: int
    minutes: float
    seed: int
    out: Path
    policy: str = "passive"
    sigma: float = 0.75
    workers: int = 1
    ray: str | None = None
    split: str | None = None
    overwrite: bool = False
    episode_minutes: float = 5.0
    warmup: float = 10.0
    px_per_cm: float = DEFAULT_PX_PER_CM
    head_speed: float | None = None
    first_episode: int = 0      # index of the first episode (a later phase of one collection)
    policy_spec: PolicySpec | None = None   # overrides policy/sigma (the SR phase's Tail)
    randomize: str | None = None    # a domain-randomization profile (`collectors.randomize`)


def parse_split(text: str | None) -> tuple[float, float, float] | None:
    if text is None:
        return None
    try:
        parts = tuple(float(p) for p in text.split("/"))
    except ValueError:
        parts = ()
    if len(parts) != 3 or not all(math.isfinite(p) and p >= 0 for p in parts):
        raise UserError(f"--split {text!r} must be three non-negative percentages like 60/10/30")
    if abs(sum(parts) - 100) > 1e-6:
        raise UserError(f"--split {text!r} sums to {sum(parts):g}, not 100; give percentages "
                        "like 60/10/30")
    return parts


def plan(req: CollectRequest) -> list[EpisodeSpec]:
    """Validate the request and cut the driving time into equal episodes."""
    cfg = scenario_for(req.scenario, req.head_speed)
    validate_chain(cfg, req.robots, req.minutes)
    if req.workers < 1:
        raise UserError(f"--workers must be at least 1, got {req.workers}")
    if req.px_per_cm <= 0:
        raise UserError(f"--px-per-cm must be positive, got {req.px_per_cm}")
    n = max(1, math.ceil(req.minutes / req.episode_minutes - 1e-9))
    seconds = req.minutes * 60 / n
    shortest = INSTANCE_STEPS / cfg.log_hz / 60
    if seconds * cfg.log_hz < INSTANCE_STEPS:
        flag, value = (("--episode-minutes", req.episode_minutes) if n > 1 else
                       ("--minutes", req.minutes))
        raise UserError(f"{flag} {value:g} is too short for one {INSTANCE_STEPS}-step instance; "
                        f"give at least {math.ceil(shortest * 100) / 100:g} minutes")
    policy = req.policy_spec or PolicyConfig(req.policy, req.sigma)
    randomize = None if req.randomize is None else Randomization.parse(req.randomize)
    return [EpisodeSpec(req.scenario, req.robots, seconds, req.warmup, req.seed, i, policy,
                        head_speed=req.head_speed, randomize=randomize)
            for i in range(req.first_episode, req.first_episode + n)]


def collect(req: CollectRequest, progress: Callable[[int, float], None] | None = None
            ) -> dict[str, Path]:
    """Run (or resume) a collection and write its datasets; returns the written paths."""
    specs = plan(req)
    fractions = parse_split(req.split)
    out = prepare_out_dir(req.out, PRODUCTS, req.overwrite)
    runner = runner_for(req.ray)
    shards = out / "shards"
    plan_json = _plan_json(specs)
    if req.overwrite and shards.exists():
        shutil.rmtree(shards)
    finished = list(shards.glob("episode_*.parquet")) if shards.is_dir() else []
    if (finished and (shards / "plan.json").exists()
            and (shards / "plan.json").read_text() != plan_json):
        raise UserError(f"{shards} holds episodes of a different collection; pass --overwrite "
                        "or choose another --out")
    shards.mkdir(parents=True, exist_ok=True)
    write_text_atomic(shards / "plan.json", plan_json)

    t0 = time.perf_counter()
    damaged = [s.index for s in specs if _shard(shards, s.index).exists()
               and not _readable(_shard(shards, s.index))]
    for index in damaged:       # atomic writes cannot truncate a shard; something else did
        _shard(shards, index).unlink()
    todo = [s for s in specs if not _shard(shards, s.index).exists()]
    done = len(specs) - len(todo)
    if progress:
        progress(done, done * specs[0].seconds / 60)
    episode_stats: dict[int, dict] = {}
    failures: dict[int, str] = {}
    for index, table, stats in runner(run_episode, todo, req.workers):
        if table is None:
            failures[index] = stats["failure"]
            continue
        decisions = stats.pop("decisions", None)
        if decisions is not None:         # before the shard: a shard means the episode is done
            with atomic_path(_shard(shards, index, "decisions")) as tmp:
                pq.write_table(decisions, tmp, compression="zstd")
        with atomic_path(_shard(shards, index)) as tmp:
            pq.write_table(table, tmp, compression="zstd")
        episode_stats[index] = stats
        done += 1
        if progress:
            progress(done, done * specs[0].seconds / 60)
    t_run = time.perf_counter() - t0
    if failures:
        index = min(failures)
        raise RunFailure(
            f"episode {index} (seeds [{req.seed}, {index}, 0..2]) failed: {failures[index]}; "
            f"{len(failures)} of {len(specs)} episodes failed; {done} finished episode(s) kept in "
            f"{shards}")
    written = assemble(req, specs, out, fractions)
    cfg = scenario_for(req.scenario, req.head_speed)
    written["manifest"] = write_manifest(
        out, "collect", {"request": asdict(req), "scenario": asdict(cfg),
                         "episodes": len(specs), "episode_seconds": specs[0].seconds},
        req.seed, {"episodes": t_run, "assemble": time.perf_counter() - t0 - t_run},
        px_per_cm=req.px_per_cm, resumed_episodes=len(specs) - len(todo),
        randomization=None if specs[0].randomize is None else asdict(specs[0].randomize),
        damaged_shards_rerun=damaged,
        episode_stats={str(k): v for k, v in sorted(episode_stats.items())},
        outputs={k: str(v) for k, v in written.items()})
    return written


def _plan_json(specs: list[EpisodeSpec]) -> str:
    """The plan as cached beside the shards: every episode's spec and the scenario's constants,
    so a collection made before a scenario's values changed (a new fit of `lab`) is not taken
    for a finished one."""
    first = specs[0]
    return json.dumps({"scenario": asdict(scenario_for(first.scenario, first.head_speed)),
                       "episodes": [asdict(s) for s in specs]}, sort_keys=True, default=str)


def finished(req: CollectRequest) -> bool:
    """Has this very collection (same plan) run to the end in `req.out`?"""
    out = Path(req.out)
    plan_file = out / "shards" / "plan.json"
    return ((out / "manifest.json").is_file() and plan_file.is_file()
            and plan_file.read_text() == _plan_json(plan(req)))


def assemble(req: CollectRequest, specs: list[EpisodeSpec], out: Path,
             fractions: tuple[float, ...] | None) -> dict[str, Path]:
    """Shards -> full log + ThymioLoc instances (tracked and truth) + optional splits."""
    cfg = scenario_for(req.scenario, req.head_speed)
    tables, tracked, truth = [], [], []
    for spec in specs:
        table = pq.read_table(_shard(out / "shards", spec.index))
        tables.append(table)
        arrays = table_arrays(table)
        first = int(round(spec.warmup * cfg.log_hz))
        starts = instance_starts(len(arrays["t"]), cfg.log_hz, first=first)
        tr = cut_instances(arrays["tracked"], starts)
        gt = cut_instances(arrays["poses"], starts)
        keep = np.all(np.isfinite(tr), axis=(1, 2, 3))    # a robot never seen yet: skip
        tracked.append(tr[keep])
        truth.append(gt[keep])
    tracked_px = to_thymioloc_pixels(np.concatenate(tracked), cfg.arena, req.px_per_cm)
    truth_px = to_thymioloc_pixels(np.concatenate(truth), cfg.arena, req.px_per_cm)
    written = {"poses": out / "poses.parquet",
               "instances": write_csv(out / "instances.csv", tracked_px),
               "instances_truth": write_csv(out / "instances_truth.csv", truth_px)}
    write_poses(written["poses"], pa.concat_tables(tables))
    decisions = []
    for spec in specs:          # a policy's per-step decisions, where it kept any (SRS)
        path = _shard(out / "shards", spec.index, "decisions")
        if path.exists():
            table = pq.read_table(path)
            decisions.append(table.append_column(
                "episode", pa.array(np.full(table.num_rows, spec.index))))
    if decisions:
        with atomic_path(out / "decisions.parquet") as tmp:
            pq.write_table(pa.concat_tables(decisions), tmp, compression="zstd")
        written["decisions"] = out / "decisions.parquet"
    if fractions is not None:
        parts = split_indices(len(tracked_px), fractions, np.random.default_rng([req.seed, 99]))
        for name, idx in zip(SPLIT_NAMES, parts, strict=True):
            if len(idx):
                written[name] = write_csv(out / f"{name}.csv", tracked_px[idx])
                written[f"{name}_truth"] = write_csv(out / f"{name}_truth.csv", truth_px[idx])
    return written


def _readable(path: Path) -> bool:
    """A shard Parquet can open (its footer intact)."""
    try:
        pq.read_metadata(path)
    except (pa.ArrowException, OSError):
        return False
    return True


def _shard(shards: Path, index: int, kind: str = "episode") -> Path:
    return shards / f"{kind}_{index:05d}.parquet"
