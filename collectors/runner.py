"""`macrostate-mj collect`: episodes in parallel (local processes or Ray), shards, datasets.

Each episode is a cached task (`core.cache`) under `OUT/cache/collect-episode/<key>/`, written
atomically by the driver as results arrive; a rerun of the same command after a kill runs only
the episodes missing, and no partial episode can exist. The datasets are assembled from the
episodes in episode order, so the CSVs are bit-identical whatever the number of workers or
the executor.
"""

from __future__ import annotations

import json
import math
import shutil
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from collectors.episodes import EpisodeSpec, run_episode
from collectors.randomize import Randomization, check_fits
from macrostate_mj.chain.filmed import check_filmed
from macrostate_mj.chain.scenario import ScenarioConfig
from macrostate_mj.chain.scenarios import ResolvesScenario
from macrostate_mj.chain.world import robot_names, validate_chain
from macrostate_mj.core.cache import TaskCache, TaskFailed, run_tasks, task_key
from macrostate_mj.core.checks import check_positive, check_seed
from macrostate_mj.core.errors import RunFailure, UserError
from macrostate_mj.core.io import atomic_path
from macrostate_mj.core.parallel import runner_for
from macrostate_mj.core.run import Run, config_hash, run_finished
from macrostate_mj.formats.instances import (
    INSTANCE_STEPS,
    cut_instances,
    instance_starts,
    split_indices,
    to_thymioloc_pixels,
)
from macrostate_mj.formats.poses import table_arrays, write_poses
from macrostate_mj.formats.thymioloc import DEFAULT_PX_PER_CM, write_csv
from macrostate_mj.tails.collection import PolicyConfig, PolicySpec

SPLIT_NAMES = ("Train", "Val", "Test")
# A request's fields that say where or how a collection runs, or what it keeps of unhealthy
# tracking, not what it makes: a resumed run may change them.
NOT_IDENTITY = ("out", "workers", "ray", "overwrite", "keep_unhealthy")
CACHE = "cache"          # the folder of a collection's cached episodes
PRODUCTS = ["instances.csv", "instances_truth.csv", "poses.parquet", "manifest.json",
            "decisions.parquet",
            *(f"{s}{t}.csv" for s in SPLIT_NAMES for t in ("", "_truth"))]


@dataclass(frozen=True)
class CollectRequest(ResolvesScenario):
    scenario: ScenarioConfig     # a name or a file is resolved on construction
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
    first_episode: int = 0      # index of the first episode (a later phase of one collection)
    policy_spec: PolicySpec | None = None   # overrides policy/sigma (the SR phase's Tail)
    randomize: str | None = None    # a domain-randomization profile (`collectors.randomize`)
    keep_unhealthy: bool = False    # assemble episodes whose tracking failed its health limits


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


def episode_count(req: CollectRequest) -> int:
    """How many equal episodes the driving time is cut into (`plan` checks the request)."""
    return max(1, math.ceil(req.minutes / req.episode_minutes - 1e-9))


def plan(req: CollectRequest) -> list[EpisodeSpec]:
    """Validate the request and cut the driving time into equal episodes."""
    cfg = req.scenario
    check_positive(req.minutes, "minutes")
    check_seed(req.seed)
    validate_chain(cfg, req.robots, req.minutes)
    check_filmed(cfg, req.robots)       # every episode tracks: refused before any
    if req.workers < 1:
        raise UserError(f"--workers must be at least 1, got {req.workers}")
    if req.px_per_cm <= 0:
        raise UserError(f"--px-per-cm must be positive, got {req.px_per_cm}")
    n = episode_count(req)
    seconds = req.minutes * 60 / n
    shortest = INSTANCE_STEPS / cfg.log_hz / 60
    if seconds * cfg.log_hz < INSTANCE_STEPS:
        flag, value = (("--episode-minutes", req.episode_minutes) if n > 1 else
                       ("--minutes", req.minutes))
        raise UserError(f"{flag} {value:g} is too short for one {INSTANCE_STEPS}-step instance; "
                        f"give at least {math.ceil(shortest * 100) / 100:g} minutes")
    policy = req.policy_spec or PolicyConfig(req.policy, req.sigma)
    randomize = None if req.randomize is None else Randomization.parse(req.randomize)
    if randomize is not None:
        check_fits(randomize, cfg)
    return [EpisodeSpec(cfg, req.robots, seconds, req.warmup, req.seed, i, policy,
                        randomize=randomize)
            for i in range(req.first_episode, req.first_episode + n)]


class EpisodeTask:
    """One episode as a cached task: keyed by its spec and the scenario's constants (a new fit
    of `lab` is not taken for a finished episode); outputs its log (and the policy's decisions,
    where it keeps any) as Parquet and its figures as JSON."""

    stage: ClassVar[str] = "collect-episode"
    version: ClassVar[int] = 3          # 3: its health judges rows, headings, hidden

    def __init__(self, spec: EpisodeSpec):
        self.spec = spec
        cfg = spec.scenario.as_made()
        fields = {k: v for k, v in asdict(spec).items() if k != "scenario"}
        if spec.randomize is not None:
            fields["randomize"] = spec.randomize.identity()
        made = {"spec": fields, "scenario": cfg}
        spread = cfg.wheel_spread > 0 or spec.randomize is not None and any(
            name == "wheel_spread" and high > 0 for name, _, high in spec.randomize.ranges)
        if spread:     # wheels that differ turn their commanded rate, not their shape, since
            made["wheel_spread"] = "rate"     # (episodes made before are not taken)
        self._key = task_key(self.stage, self.version, made)

    def key(self) -> str:
        """Hashed once: the runner, the resume count and the assembly all ask for it."""
        return self._key

    def compute(self) -> dict[str, bytes]:
        _, table, stats = run_episode(self.spec)
        if table is None:
            raise TaskFailed(stats["failure"])
        files = {"episode.parquet": _parquet_bytes(table)}
        decisions = stats.pop("decisions", None)
        if decisions is not None:
            files["decisions.parquet"] = _parquet_bytes(decisions)
        files["stats.json"] = json.dumps(stats, sort_keys=True).encode()
        return files


def tracking_verdict(req: CollectRequest, stats: dict[int, dict]) -> dict:
    """A collection's tracking health: each episode judged against the scenario's `[tracking]`
    limits, the worst figures per robot over its episodes (`health`, and in one line), and
    whether unhealthy episodes were kept."""
    from macrostate_mj.vision.health import TrackingHealth, worst_of

    cfg = req.scenario
    names = robot_names(req.robots)
    reports = {i: TrackingHealth.from_dict(s["health"], names)
               for i, s in sorted(stats.items())}
    findings = {str(i): [f.describe() for f in r.judged(cfg)] for i, r in reports.items()}
    findings = {i: lines for i, lines in findings.items() if lines}
    worst = worst_of(list(reports.values()))
    return {"summary": worst.described(cfg),
            "health": worst.as_dict(),
            "healthy": not findings, "limits": cfg.tracking, "findings": findings,
            "keep_unhealthy": req.keep_unhealthy}


def _parquet_bytes(table: pa.Table) -> bytes:
    sink = pa.BufferOutputStream()
    pq.write_table(table, sink, compression="zstd")
    return sink.getvalue().to_pybytes()


def run_config(req: CollectRequest, specs: list[EpisodeSpec]) -> dict:
    """What a collection's outputs depend on (not where or how fast it runs): its run's
    identity, so a resumed run may change --workers but not the collection. A randomization
    profile counts by its ranges, not by the path of its file: a folder moved with its
    profile beside it resumes."""
    identity = {k: v for k, v in asdict(req).items()
                if k not in (*NOT_IDENTITY, "scenario", "randomize")}
    drawn = specs[0].randomize
    return {"request": identity,
            "scenario": asdict(req.scenario.as_made()),
            "randomize": None if drawn is None else drawn.identity(),
            "episodes": len(specs), "episode_seconds": specs[0].seconds}


def collect(req: CollectRequest, progress: Callable[[int, float, float], None] | None = None
            ) -> dict[str, Path]:
    """Run (or resume) a collection and write its datasets; returns the written paths.
    `progress(episodes, sim minutes, sim minutes resumed)` follows the episodes."""
    specs = plan(req)
    fractions = parse_split(req.split)
    runner_for(req.ray)                                  # an unreachable cluster: bad input now
    cache = TaskCache(Path(req.out) / CACHE)
    with Run(req.out, "collect", run_config(req, specs), req.seed, PRODUCTS,
             req.overwrite) as run:
        tasks = [EpisodeTask(s) for s in specs]
        damaged = [t.spec.index for t in tasks if not _intact(cache, t)]
        done, resumed = 0, 0
        failures: dict[int, str] = {}
        with run.stage("episodes"):
            for outcome in run_tasks(cache, tasks, req.workers, req.ray):
                if outcome.folder is None:
                    failures[outcome.task.spec.index] = outcome.failure or "failed"
                    continue
                done += 1
                resumed += outcome.cached
                if progress:
                    progress(done, done * specs[0].seconds / 60, resumed * specs[0].seconds / 60)
        if failures:
            index = min(failures)
            raise RunFailure(
                f"episode {index} (seeds [{req.seed}, {index}, 0..2]) failed: {failures[index]}; "
                f"{len(failures)} of {len(specs)} episodes failed; {done} finished episode(s) "
                f"kept in {cache.root}")
        folders = [cache.folder(t.stage, t.key()) for t in tasks]
        stats = {t.spec.index: json.loads((f / "stats.json").read_text())
                 for t, f in zip(tasks, folders, strict=True)}
        tracking = tracking_verdict(req, stats)
        run.record(tracking=tracking,
                   episode_stats={str(k): v for k, v in sorted(stats.items())})
        if tracking["findings"] and not req.keep_unhealthy:
            index, line = next(iter(tracking["findings"].items()))
            raise RunFailure(
                f"tracking unhealthy in episode {index}: {line[0]}; "
                f"{len(tracking['findings'])} of {len(specs)} episodes unhealthy, no dataset "
                f"assembled (episodes kept in {cache.root}); pass --keep-unhealthy to assemble "
                "them anyway")
        with run.stage("assemble"):
            written = assemble(req, specs, folders, fractions)
        written["manifest"] = run.path
        run.record(px_per_cm=req.px_per_cm, workers=req.workers, ray=req.ray,
                   scenario_hash=config_hash(req.scenario),
                   resumed_episodes=resumed, damaged_shards_rerun=damaged,
                   randomization=None if specs[0].randomize is None
                   else asdict(specs[0].randomize),
                   outputs={k: str(v) for k, v in written.items()})
    return written


def _intact(cache: TaskCache, task: EpisodeTask) -> bool:
    """False for a cached episode whose Parquet cannot be opened (a copy cut short, a full
    disk): its folder is removed, so the episode is simulated again."""
    folder = cache.folder(task.stage, task.key())
    if not folder.is_dir() or _readable(folder / "episode.parquet"):
        return True
    shutil.rmtree(folder)
    return False


def finished(req: CollectRequest) -> bool:
    """Has this very collection (same request and scenario constants) run to the end in
    `req.out`?"""
    return run_finished(Path(req.out), run_config(req, plan(req)))


def assemble(req: CollectRequest, specs: list[EpisodeSpec], folders: list[Path],
             fractions: tuple[float, ...] | None) -> dict[str, Path]:
    """Episodes (in episode order) -> full log + ThymioLoc instances (tracked and truth) +
    optional splits."""
    cfg = req.scenario
    out = Path(req.out)
    tables, tracked, truth = [], [], []
    for spec, folder in zip(specs, folders, strict=True):
        table = pq.read_table(folder / "episode.parquet")
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
    for spec, folder in zip(specs, folders, strict=True):   # a policy's decisions (SRS)
        path = folder / "decisions.parquet"
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
