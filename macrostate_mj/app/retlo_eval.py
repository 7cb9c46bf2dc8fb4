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
    """The report written to `out` (and returned). `calibration` None: on exactly when the
    module has uncertainty; True on a point module is refused before anything is written. An
    uncertain module's estimates are then its Monte Carlo mixtures' means (`propagate`)."""
    module, name = loaded
    uncertain = bool(getattr(module, "uncertain", False))
    calibrate = uncertain if calibration is None else calibration
    if calibrate:
        require_uncertain(module)
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
