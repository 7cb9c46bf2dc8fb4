"""`evaluate retlo` as a use case: a loaded module (one checkpoint, the heuristic, or a deep
ensemble) on one ThymioLoc file → its report, and on request a video and a rerun recording of
the first instances, with 90 % ellipses where the module has uncertainty; and the tables of
such reports the docs show (`calibrate retlo`'s comparison)."""

from __future__ import annotations

import json
from pathlib import Path

from estimators.retlo.api import as_world, predict, report
from estimators.retlo.chain import Module
from estimators.retlo.gaussian import GAUSSIAN_REGIONS
from estimators.retlo.propagate import require_uncertain
from estimators.retlo.report import chain_positions
from macrostate_mj.app.results.sources import root, source, stat
from macrostate_mj.core.evidence import ClaimsError, Q, Table, dig
from macrostate_mj.core.io import check_writable_file, write_json_atomic
from macrostate_mj.core.run import Run
from macrostate_mj.core.stats import mean_std

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


# The reports of `calibrate retlo`'s comparison as the docs show them --------------------------

REFIT_KEYS = ("coverage_50", "coverage_90", "gaussian_coverage_50", "gaussian_coverage_90")


def _arm(folder: str, arm: str) -> list[dict]:
    """The `evaluate retlo` reports of one arm of a `calibrate retlo` comparison, a seed each
    (`reports/<arm>_s<seed>.json`)."""
    found = sorted((root() / folder / "reports").glob(f"{arm}_s*.json"))
    if not found:
        raise ClaimsError(f"results/{folder}/reports holds no {arm}_s*.json")
    return [json.loads(p.read_text()) for p in found]


@source
def refit(folder: str, arm: str, keypath: str, fmt: str = ".2f") -> Q:
    """One figure of a `calibrate retlo` arm's reports, mean ± std over its seeds."""
    ms = mean_std([float(dig(r, keypath)) for r in _arm(folder, arm)])  # type: ignore[arg-type]
    return Q(ms["mean"], ms["std"], fmt, "")


@source
def retlo_refit(folder: str) -> Table:
    """`calibrate retlo` (results/retlo_lab5_calibrated): per arm and robot, the coverage of the
    model's regions and of the plain Gaussian's χ² regions, mean ± std over model seeds (each
    seed's `evaluate retlo` report on the test chains)."""
    rows = [["regions fitted on", "robot", "coverage 50 %", "coverage 90 %", "Gaussian χ² 50 %",
             "Gaussian χ² 90 %"]]
    label = {"trained": "lab 3-robot validation (training)",
             "refitted": "lab 5-robot chains, seed 3 (calibrate retlo)"}
    for arm in label:
        reports = _arm(folder, arm)
        for who in (w for w in reports[0]["calibration"] if w != "nll_unit"):
            rows.append([label[arm], who, *(stat(mean_std(
                [r["calibration"][who][k] for r in reports]), ".2f") for k in REFIT_KEYS)])
    return rows
