"""Library API of `macrostate-mj simulate`: validate everything, run, write atomically.

This is the top of the data flow: the run is `collectors.simulate`'s, the recorders that draw
it `viz`'s; here they are wired together and the outputs written.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from macrostate_mj.chain.scenario import ScenarioConfig
from macrostate_mj.chain.scenarios import SCENARIOS, ResolvesScenario
from macrostate_mj.chain.world import validate_chain
from macrostate_mj.core.errors import RunFailure, UserError
from macrostate_mj.core.io import check_writable_file
from macrostate_mj.core.run import Run
from macrostate_mj.formats.poses import write_poses

if TYPE_CHECKING:
    from macrostate_mj.chain.sim import ChainSim, Hook, PoseLog, Tracker
    from macrostate_mj.vision.camera_chain import CameraChain


@dataclass(frozen=True)
class SimulateRequest(ResolvesScenario):
    scenario: ScenarioConfig     # a name or a file is resolved on construction
    robots: int
    seconds: float
    seed: int
    out: Path
    video: Path | None = None
    rerun: Path | None = None
    overwrite: bool = False
    video_fps: float = 10.0
    track: bool = False
    overlays: str = "all"
    video_view: str = "camera"           # viz.video.VIEWS: through the lens, or undistorted
    camera_video: Path | None = None     # the tracker's raw frames (+ FILE.times.csv)


def parse_overlays(text: str) -> tuple[str, ...]:
    from viz.video import OVERLAYS

    if text.strip() == "all":
        return OVERLAYS
    names = () if text.strip() == "none" else tuple(n.strip() for n in text.split(",") if n)
    bad = [n for n in names if n not in OVERLAYS]
    if bad:
        raise UserError(f"unknown overlay {bad[0]!r}; choose from {', '.join(OVERLAYS)}, all or "
                        "none")
    return names


def check_request(req: SimulateRequest) -> ScenarioConfig:
    """Every check of a simulate request, before anything is built or written."""
    cfg = req.scenario
    parse_overlays(req.overlays)
    validate_chain(cfg, req.robots, req.seconds)
    if req.track:       # anything in view taken for a colour marker, tags too narrow to read
        from macrostate_mj.chain.filmed import check_filmed

        check_filmed(cfg, req.robots)
    _run(req, cfg).claim()
    from viz.video import VIEWS, times_path

    if req.video_view not in VIEWS:
        raise UserError(f"--video-view {req.video_view!r} is not one of {', '.join(VIEWS)}")
    if req.camera_video is not None and not req.track:
        raise UserError("--camera-video films what the tracker is handed; add --track")
    outputs = ((req.video, "--video", ".mp4"), (req.rerun, "--rerun", ".rrd"),
               (req.camera_video, "--camera-video", ".mp4"))
    for path, flag, suffix in outputs:
        if path is not None:
            if path.suffix != suffix:
                raise UserError(f"{flag} {path} needs the {suffix} extension")
            check_writable_file(path, req.overwrite, flag)
    if req.camera_video is not None:
        check_writable_file(times_path(req.camera_video), req.overwrite, "--camera-video")
    return cfg


def simulate_run(req: SimulateRequest, progress=None) -> dict[str, Path]:
    """Run one simulation; returns the written paths. Nothing is written if validation fails."""
    from collectors.simulate import simulate_chain

    cfg = check_request(req)
    out = req.out
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise UserError(f"cannot create --out {out}: {err.strerror}; "
                        "choose a writable folder") from None
    with _run(req, cfg) as run:
        ran = simulate_chain(cfg, req.robots, req.seconds, req.seed, req.track,
                             lambda sim, tracker: _recorders(req, cfg, sim, tracker), progress)
        sim, chain, failure = ran.sim, ran.tracker, ran.failure
        write_poses(out / "poses.parquet", ran.poses())
        written = {"poses": out / "poses.parquet"}
        if req.video is not None:
            written["video"] = req.video
        if req.rerun is not None:
            written["rerun"] = req.rerun
        if req.camera_video is not None:
            from viz.video import times_path

            written["camera"] = req.camera_video
            written["times"] = times_path(req.camera_video)
        written["manifest"] = run.path
        run.timings.update(ran.timings)
        run.record(robots=ran.world.names, outputs={k: str(v) for k, v in written.items()},
                   timestep=ran.world.model.opt.timestep,
                   realtime_factor=sim.time / max(ran.timings["run"], 1e-9),
                   fault=None if failure is None else {**asdict(failure.fault),
                                                       "fault": failure.fault.fault.name,
                                                       "reason": str(failure)},
                   simulated_seconds=sim.time, health=asdict(sim.monitor.stats),
                   tracking=None if chain is None else tracking_record(chain, cfg, ran.log))
        if failure is not None:
            raise RunFailure(f"physics failed: {failure} (seed {req.seed}); poses and video up "
                             f"to then are in {out}; reproduce: {reproduce_command(req)}")
        findings = [] if chain is None else run.extra["tracking"]["findings"]
        if findings:
            more = f" (and {len(findings) - 1} more)" if len(findings) > 1 else ""
            raise RunFailure(f"tracking unhealthy: {findings[0]}{more}; poses kept in {out}, "
                             "every finding in its manifest")
    return written


def tracking_record(chain: CameraChain, cfg: ScenarioConfig, log: PoseLog) -> dict:
    """A tracked run's `tracking` block: frame counts, the noise, and its health (frames and
    the rows of `log`, the dataset) against the scenario's limits (`vision.health`)."""
    health = chain.health.report(log)
    findings = [f.describe() for f in health.judged(cfg)]
    return {"frames": chain.frames, "dropped": chain.dropped, "noise": chain.noise,
            "marker_jitter_m": cfg.marker_jitter, "health": health.as_dict(),
            "limits": cfg.tracking, "summary": health.described(cfg),
            "healthy": not findings, "findings": findings}


def tracking_summary(manifest: Path) -> str:
    """The one-line tracking health of a finished run (a simulation, a collection, an SRS
    collection), from its manifest: the one home of that line."""
    import json

    tracking = json.loads(Path(manifest).read_text()).get("tracking") or {}
    healthy = tracking.get("healthy")
    state = {True: "healthy", None: "not judged"}.get(healthy, "UNHEALTHY")
    if healthy is False and tracking.get("keep_unhealthy"):
        state += " (kept: --keep-unhealthy)"
    return f"{state}: {tracking.get('summary', 'no tracking recorded')}"


def _run(req: SimulateRequest, cfg: ScenarioConfig) -> Run:
    """The run lifecycle of a request: what its outputs depend on, not where they go."""
    identity = {k: v for k, v in asdict(req).items() if k not in ("out", "overwrite")}
    return Run(req.out, "simulate", {"request": identity, "scenario": asdict(cfg)}, req.seed,
               ["poses.parquet"], req.overwrite)


def _recorders(req: SimulateRequest, cfg: ScenarioConfig, sim: ChainSim,
               tracker: Tracker | None) -> list[Hook]:
    """The recording hooks the request asks for: an overhead video (the camera's view, or the
    undistorted one), a rerun recording, the camera's raw frames (after the camera chain)."""
    hooks: list[Hook] = []
    if req.video is not None:
        from viz.video import VideoRecorder

        hooks.append(VideoRecorder(req.video, sim, fps=req.video_fps,
                                   overlays=parse_overlays(req.overlays), tracker=tracker,
                                   view=req.video_view))
    if req.camera_video is not None and tracker is not None:
        from viz.video import CameraVideo

        hooks.append(CameraVideo(req.camera_video, tracker, cfg.command_hz))
    if req.rerun is not None:
        from viz.rerun_log import RerunRecorder

        hooks.append(RerunRecorder(req.rerun, sim, rate_hz=cfg.log_hz, phase=sim.log_phase,
                                   tracker=tracker))
    return hooks


def scenario_arg(cfg: ScenarioConfig) -> str:
    """How a command line names a scenario: a built-in's name (with `--head-speed` where only
    that differs), else a file holding it (the run's manifest has it whole: `macrostate-mj
    scenario show` writes one from a name)."""
    builtin = SCENARIOS.get(cfg.name)
    if builtin == cfg:
        return cfg.name
    if builtin is not None and builtin.with_overrides(head_speed=cfg.head_speed) == cfg:
        return f"{cfg.name} --head-speed {cfg.head_speed:g}"
    return f"{cfg.name}.toml"


def reproduce_command(req: SimulateRequest) -> str:
    """The CLI line that reruns this request's simulation (same trajectory on this machine)."""
    parts = ["macrostate-mj simulate", f"--scenario {scenario_arg(req.scenario)}",
             f"--robots {req.robots}",
             f"--seconds {req.seconds:g}", f"--seed {req.seed}"]
    if req.track:
        parts.append("--track")
    return " ".join([*parts, f"--out {req.out}", "--overwrite"])
