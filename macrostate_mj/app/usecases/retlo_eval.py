"""`evaluate retlo` as a use case: a loaded module (one checkpoint, the heuristic, or a deep
ensemble) on one ThymioLoc file → its report, and on request a video and a rerun recording of
the first instances, with 90 % ellipses where the module has uncertainty."""

from __future__ import annotations

from pathlib import Path

from estimators.retlo.api import as_world, predict, report
from estimators.retlo.chain import Module
from estimators.retlo.gaussian import GAUSSIAN_REGIONS
from estimators.retlo.propagate import require_uncertain
from estimators.retlo.report import chain_positions
from macrostate_mj.core.io import check_writable_file, write_json_atomic
from macrostate_mj.core.run import Run

SHOWN = 3    # instances in the video and the recording


def outputs_checked(out: Path, video: Path | None, rerun: Path | None, overwrite: bool) -> None:
    """Every output writable, before any work."""
    check_writable_file(out, overwrite, "--out")
    for path, flag in ((video, "--video"), (rerun, "--rerun")):
        if path is not None:
            check_writable_file(path, overwrite, flag)


def evaluate_request(loaded: tuple[Module, str], data: Path, out: Path, px_per_cm: float,
                     calibration: bool | None, particles: int, seed: int,
                     video: Path | None = None, rerun: Path | None = None) -> dict:
    """The report written to `out` (and returned), its manifest beside it
    (`<out>.manifest.json`). `calibration` None: on exactly when the module has uncertainty;
    True on a point module is refused before anything is written. An uncertain module's
    estimates are then its Monte Carlo mixtures' means (`propagate`)."""
    module, name = loaded
    uncertain = bool(getattr(module, "uncertain", False))
    calibrate = uncertain if calibration is None else calibration
    if calibrate:
        require_uncertain(module)
    config = {"model": name, "data": str(data), "px_per_cm": px_per_cm,
              "calibration": calibrate, "particles": particles,
              "video": None if video is None else str(video),
              "rerun": None if rerun is None else str(rerun)}
    # the outputs were checked (`outputs_checked`), so the run claims the folder as is
    with Run(out.parent, "evaluate retlo", config, seed, [out.name], overwrite=True,
             manifest=out.name + ".manifest.json") as run:
        with run.stage("evaluate"):
            result = _evaluate(module, name, data, out, px_per_cm, calibrate, uncertain,
                               particles, seed, video, rerun)
        run.record(mean_error_cm=result["mean_error_cm"], n_instances=result["n_instances"])
    return result


def _evaluate(module: Module, name: str, data: Path, out: Path, px_per_cm: float,
              calibrate: bool, uncertain: bool, particles: int, seed: int,
              video: Path | None, rerun: Path | None) -> dict:
    world = as_world(data, px_per_cm)
    drawn = uncertain and (video is not None or rerun is not None)   # ellipses need Σ
    est, cov = predict(module, world, gaussian=calibrate or drawn, particles=particles,
                       seed=seed)
    result = {"model": name, "data": str(data), "px_per_cm": px_per_cm,
              **report(module, world, est, cov if calibrate else None, particles, seed)}
    shown = slice(0, SHOWN)
    if cov is not None:    # the drawn 90 % ellipses are the model's 90 % regions
        position = chain_positions(world.shape[2])[None, None, :]
        cov = getattr(module, "regions", GAUSSIAN_REGIONS).outline_cov(cov, 0.9, position)
    if video is not None:
        from viz.retlo_figures import write_video_gaussian

        write_video_gaussian(video, world[shown], est[shown],
                             None if cov is None else cov[shown], px_per_cm)
    if rerun is not None:
        from viz.rerun_log import log_chain_estimates

        log_chain_estimates(rerun, world[shown], est[shown], None if cov is None else cov[shown])
    write_json_atomic(out, result)
    return result
