"""`collect --policy srs`: the two phases of seed §3.3 as one resumable collection.

1. RO (Rand-Only): `ro_instances` instances with the Tail's destination perturbed at random
   (`OUT/ro/`, an ordinary collection);
2. the novelty models (φ, ψ, ζ) trained on the RO phase's ground-truth tracks, or its tracked
   ones with `track`: a cached task (`OUT/cache/srs-novelty/<key>/`) keyed by the training
   settings and the bytes of the RO data, copied to `OUT/novelty.pt`;
3. SR (Selective-Random): `instances - ro_instances` more with the SRS Tail (`OUT/sr/`, with
   `decisions.parquet`: per scored step the k candidates' offsets, e and the pick);
4. the dataset in `OUT/`: the RO instances then the SR ones, in the ThymioLoc layout.
The whole runs under the one run lifecycle (`core.run.Run`); each stage is cached, so a rerun
after a kill resumes where it stopped (the collections episode by episode) and `finished_srs`
tells a caller whether this very collection is done. SR episodes take indices after the RO
ones, so no episode repeats another's seeds.
The novelty models come through `NoveltyTrainer`, which the caller passes in: `collectors` and
`estimators` are independent layers (pyproject's import contract).
"""

from __future__ import annotations

import hashlib
import json
import math
import shutil
import tempfile
from collections.abc import Callable
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Protocol

import numpy as np

from collectors.runner import (
    CACHE,
    NOT_IDENTITY,
    SPLIT_NAMES,
    CollectRequest,
    collect,
    finished,
    parse_split,
    plan,
)
from macrostate_mj.core.cache import TaskCache, task_key
from macrostate_mj.core.errors import UserError
from macrostate_mj.core.io import atomic_path
from macrostate_mj.core.run import Run, run_finished
from macrostate_mj.formats.instances import (
    INSTANCE_STEPS,
    from_thymioloc_pixels,
    instance_starts,
    split_indices,
)
from macrostate_mj.formats.srs_windows import NoveltySource
from macrostate_mj.formats.thymioloc import read_csv, write_csv
from macrostate_mj.tails.collection import PolicyConfig, PolicySpec
from macrostate_mj.tails.srs import SRSConfig, check_srs

NOVELTY = "novelty.pt"
NOVELTY_STAGE, NOVELTY_VERSION = "srs-novelty", 1   # bump when the models change for the same data
PRODUCTS = ["instances.csv", "instances_truth.csv", "decisions.parquet", NOVELTY,
            *(f"{s}{t}.csv" for s in SPLIT_NAMES for t in ("", "_truth"))]


@dataclass(frozen=True)
class SRSRequest:
    base: CollectRequest        # scenario, robots, seed, out, workers, split, ... (policy unused)
    pick: str
    instances: int
    ro_instances: int
    k: int = 30
    track: bool = False         # the Tail acts on, and its models learn from, tracked poses


class NoveltyTrainer(Protocol):
    """The novelty models' stage as this collection needs it, without knowing how they are made
    (`estimators.srs.novelty.NoveltyTraining`, passed in by `app`)."""

    def config(self, seed: int) -> object:
        """The training settings for a collection of `seed`; their repr keys the cached model."""
        ...

    def train(self, tracks: np.ndarray, config: object, scenario: str, path: Path,
              data_key: str, progress: bool) -> None:
        """Train on RO team tracks (instances, steps, n, 3) and store the models at `path`."""
        ...

    def source(self, path: Path, sha256: str) -> NoveltySource:
        """The stored models as the SR phase's Tail loads them in each episode."""
        ...


def episodes_for(req: CollectRequest, instances: int) -> int:
    """Episodes of `req.episode_minutes` that yield at least `instances` instances (the log's
    first step may come up to one period late: counted without it)."""
    cfg = req.scenario
    steps = int(math.floor((req.warmup + req.episode_minutes * 60) * cfg.log_hz)) - 1
    per = len(instance_starts(steps, cfg.log_hz, first=int(round(req.warmup * cfg.log_hz))))
    if per < 1:
        raise UserError(f"--episode-minutes {req.episode_minutes:g} is too short for one "
                        f"{INSTANCE_STEPS}-step instance")
    return math.ceil(instances / per)


def _phase(req: SRSRequest, name: str, instances: int, first: int, policy: PolicySpec
           ) -> CollectRequest:
    base = req.base
    n = episodes_for(base, instances)
    return replace(base, out=base.out / name, minutes=n * base.episode_minutes, split=None,
                   first_episode=first, policy_spec=policy)


def validate(req: SRSRequest) -> None:
    """Refuse a request the phases cannot serve, before anything is written."""
    if req.ro_instances < 2:
        raise UserError(f"--ro-instances must be at least 2, got {req.ro_instances}")
    if req.ro_instances >= req.instances:
        raise UserError(f"--ro-instances {req.ro_instances} leaves no SR phase within "
                        f"--instances {req.instances}; give fewer RO instances than instances")
    check_srs(req.pick, req.k, req.base.sigma)
    if req.base.robots < 3:
        raise UserError(f"--policy srs needs a team of at least 3 robots, got {req.base.robots}")


def run_config(req: SRSRequest, novelty: NoveltyTrainer) -> dict:
    """What an SRS collection's outputs depend on (not where or how fast it runs): its run's
    identity, so a resumed run may change --workers but not the collection."""
    base = {k: v for k, v in asdict(req.base).items() if k not in NOT_IDENTITY}
    return {"request": base, "pick": req.pick, "instances": req.instances,
            "ro_instances": req.ro_instances, "k": req.k, "track": req.track,
            "scenario": asdict(req.base.scenario.as_made()),
            "novelty": repr(novelty.config(req.base.seed))}


def finished_srs(req: SRSRequest, novelty: NoveltyTrainer) -> bool:
    """Has this very collection (same request, scenario constants and novelty settings) run to
    the end in `req.base.out`?"""
    return run_finished(Path(req.base.out), run_config(req, novelty))


def collect_srs(req: SRSRequest, novelty: NoveltyTrainer,
                progress: Callable[[str, int, int], None] | None = None) -> dict[str, Path]:
    """Run (or resume) the four stages, the models made by `novelty`; returns the written
    paths."""
    validate(req)
    fractions = parse_split(req.base.split)
    out = Path(req.base.out)
    ro_req = _phase(req, "ro", req.ro_instances, 0, PolicyConfig("random", req.base.sigma))
    n_ro = len(plan(ro_req))                      # bad input: refused before anything is written
    with Run(out, "collect --policy srs", run_config(req, novelty), req.base.seed, PRODUCTS,
             req.base.overwrite) as run:
        with run.stage("ro_phase"):               # the phases are this run's: never refused
            if not finished(ro_req):
                collect(replace(ro_req, overwrite=True), _reporter(progress, "RO phase", n_ro))
        with run.stage("novelty_models"):
            key, model_path = _novelty(req, ro_req, novelty, TaskCache(out / CACHE),
                                       progress is not None)
        with run.stage("sr_phase"):
            sha = hashlib.sha256(model_path.read_bytes()).hexdigest()
            srs = SRSConfig(novelty.source(model_path.resolve(), sha), req.pick, req.k,
                            req.base.sigma, track=req.track)
            sr_req = _phase(req, "sr", req.instances - req.ro_instances, n_ro, srs)
            if not finished(sr_req):
                collect(replace(sr_req, overwrite=True),
                        _reporter(progress, f"SR phase (SRS-{req.pick})", len(plan(sr_req))))
        with run.stage("assemble"):
            with atomic_path(out / "decisions.parquet") as tmp:
                shutil.copyfile(sr_req.out / "decisions.parquet", tmp)
            written = _assemble(req, ro_req, sr_req, fractions) | {
                "novelty": model_path, "decisions": out / "decisions.parquet"}
        written["manifest"] = run.path
        phases = {"ro": _tracking(ro_req), "sr": _tracking(sr_req)}
        known = [t["healthy"] for t in phases.values() if "healthy" in t]
        run.record(tracking={"healthy": all(known) if len(known) == len(phases) else None,
                             "summary": "; ".join(
                                 f"{k.upper()} phase {t.get('summary', 'not recorded')}"
                                 for k, t in phases.items()),
                             "keep_unhealthy": req.base.keep_unhealthy, "phases": phases},
                   phases={"ro": str(ro_req.out), "sr": str(sr_req.out)}, novelty_sha256=sha,
                   novelty_key=key, workers=req.base.workers, ray=req.base.ray,
                   outputs={k: str(v) for k, v in written.items()})
    return written


def _tracking(phase: CollectRequest) -> dict:
    """A phase's tracking health, as its own collection's manifest records it."""
    manifest = json.loads((Path(phase.out) / "manifest.json").read_text())
    return manifest.get("tracking") or {}


def _novelty(req: SRSRequest, ro_req: CollectRequest, novelty: NoveltyTrainer,
             cache: TaskCache, show: bool) -> tuple[str, Path]:
    """The novelty models as a cached task keyed by their settings and the RO data's bytes
    (the same RO phase and settings train once), copied to `OUT/novelty.pt` when it differs
    (so an unchanged model keeps its file, and the SR episodes their keys)."""
    cfg = novelty.config(req.base.seed)
    data = ro_req.out / ("instances.csv" if req.track else "instances_truth.csv")
    scenario = req.base.scenario
    key = task_key(NOVELTY_STAGE, NOVELTY_VERSION,
                   {"config": repr(cfg), "ro_instances": req.ro_instances,
                    "scenario": scenario.name, "constants": scenario,
                    "px_per_cm": req.base.px_per_cm}, [data])

    def compute() -> dict[str, bytes]:
        tracks = _tracks(data, ro_req, req.ro_instances)
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / NOVELTY
            novelty.train(tracks, cfg, scenario.name, path, key, show)
            return {NOVELTY: path.read_bytes()}

    model = (cache.cached(NOVELTY_STAGE, key, compute) / NOVELTY).read_bytes()
    final = Path(req.base.out) / NOVELTY
    if not final.is_file() or final.read_bytes() != model:
        with atomic_path(final) as tmp:
            tmp.write_bytes(model)
    return key, final


def _reporter(progress: Callable[[str, int, int], None] | None, stage: str, total: int
              ) -> Callable[[int, float], None] | None:
    if progress is None:
        return None
    return lambda done, _minutes, _resumed: progress(stage, done, total)


def _tracks(path: Path, req: CollectRequest, count: int) -> np.ndarray:
    """The first `count` instances of a collection's truth CSV as world tracks (m, rad)."""
    cfg = req.scenario
    px = read_csv(path).poses[:count].astype(float)
    return from_thymioloc_pixels(px, cfg.arena, req.px_per_cm)


def _assemble(req: SRSRequest, ro: CollectRequest, sr: CollectRequest,
              fractions: tuple[float, ...] | None) -> dict[str, Path]:
    """The RO phase's first instances, then the SR phase's, as one dataset (and splits)."""
    out = req.base.out
    counts = ((ro.out, req.ro_instances), (sr.out, req.instances - req.ro_instances))
    written = {}
    for kind in ("", "_truth"):
        parts = []
        for folder, count in counts:
            poses = read_csv(folder / f"instances{kind}.csv").poses
            if len(poses) < count:
                raise UserError(f"{folder} holds {len(poses)} instances, fewer than the "
                                f"{count} asked for; rerun with --overwrite")
            parts.append(poses[:count])
        poses = np.concatenate(parts)
        written[f"instances{kind}"] = write_csv(out / f"instances{kind}.csv", poses)
        if fractions is not None:
            split = split_indices(len(poses), fractions,
                                  np.random.default_rng([req.base.seed, 99]))
            for name, idx in zip(SPLIT_NAMES, split, strict=True):
                if len(idx):
                    written[f"{name}{kind}"] = write_csv(out / f"{name}{kind}.csv", poses[idx])
    return written
