"""`experiment sim2real`'s data: the real folds' files checked and read, the lab collections
(as written, fitted per fold or on Train, drawn from a range candidate, ablated)."""

from __future__ import annotations

import json
from numbers import Integral
from pathlib import Path

import numpy as np

from collectors.runner import CollectRequest, collect, finished
from macrostate_mj.app.experiments import Progress
from macrostate_mj.app.experiments.sim2real.config import (
    ARMS,
    FITS,
    PLAIN,
    REAL_FILES,
    SIM_SELECT,
    Config,
)
from macrostate_mj.chain.scenarios import get_scenario
from macrostate_mj.core.cache import task_key
from macrostate_mj.core.errors import UserError
from macrostate_mj.core.io import write_json_atomic
from macrostate_mj.formats.thymioloc import read_csv


def _require_splits(folder: Path, flag: str, hint: str, files: tuple[str, ...] = REAL_FILES
                    ) -> None:
    """One-line error unless `folder` holds `files` (Train.csv and Val.csv)."""
    missing = [f for f in files if not (folder / f).is_file()]
    if missing:
        raise UserError(f"{flag} {folder} has no {missing[0]}; pass {hint}")


def read_real(folder: Path, train_only: bool = False) -> np.ndarray:
    """The pooled real instances (px, degrees), Train then Val (Train alone with
    `train_only`: Val.csv is not even opened); one-line errors otherwise."""
    files = REAL_FILES[:1] if train_only else REAL_FILES
    _require_splits(folder, "--real", "the folder of the real ThymioLoc Train.csv and Val.csv "
                    "(`macrostate-mj data fetch retlo` gets them)", files)
    parts = [read_csv(folder / f).poses for f in files]
    if len({p.shape[1:] for p in parts}) != 1 or parts[0].shape[2] != 3:
        raise UserError(f"--real {folder}: Train.csv and Val.csv must both hold 3-robot "
                        "instances of the same length")
    return np.concatenate(parts)


def validate(config: Config) -> np.ndarray:
    """Refuse bad inputs in one line before anything is written; the pooled real instances."""
    from collectors.randomize import PARAMETERS, Randomization

    if config.sim is not None and config.lab != get_scenario("lab"):
        raise UserError("--scenario names the lab this command collects in; drop it or --sim")
    for weight in config.mix_weight:
        if not 0.0 < weight < 1.0:
            raise UserError(f"--mix-weight {weight:g}: the lab data's share of the mixed arm's "
                            "loss must be in (0, 1)")
    for epochs in config.finetune_epochs:
        if isinstance(epochs, bool) or not isinstance(epochs, int) or epochs < 1:
            # a numpy integer is refused too (the results file could not hold it): say so
            kind = f" ({type(epochs).__name__}: pass int(...))" if isinstance(
                epochs, Integral) and not isinstance(epochs, int) else ""
            raise UserError(f"--finetune-epochs {epochs}{kind}: the fine-tuned arms' epochs must "
                            "be whole numbers of at least 1")
    if not config.finetune_epochs:
        raise UserError("--finetune-epochs: name at least one count (30 by default)")
    if config.sim_select not in SIM_SELECT:
        raise UserError(f"--sim-select {config.sim_select}: choose {' or '.join(SIM_SELECT)}")
    pooled = read_real(config.real, config.train_only)
    unknown = [a for a in config.arms if a not in ARMS]
    if unknown or not config.arms:
        raise UserError(f"--arm {', '.join(unknown) or '(none)'}: choose among "
                        f"{', '.join(ARMS)}")
    if config.folds > len(pooled):
        raise UserError(f"--real {config.real} holds {len(pooled)} instances, fewer than "
                        f"{config.folds} folds")
    if config.sim is not None:
        _require_splits(config.sim, "--sim", "a `collect --split` folder")
        if config.randomize:
            raise UserError("--randomize applies to the lab collection this command makes; "
                            "drop it or --sim")
    if len(set(config.randomize)) != len(config.randomize):
        raise UserError(f"--randomize {', '.join(config.randomize)}: name each candidate once")
    for profile in config.randomize:
        if profile != PLAIN:
            Randomization.parse(profile)
    bad = [f for f in config.fits if f not in FITS]
    if bad or not config.fits or len(set(config.fits)) != len(config.fits):
        raise UserError(f"--fit {', '.join(bad or config.fits) or '(none)'}: name each of "
                        f"{', '.join(FITS)} at most once")
    if config.fits != ("none",) and config.sim is not None:
        raise UserError("--fit fits the lab collection this command makes; drop it or --sim")
    if config.ablate and (config.sim is not None or
                          config.fits[0] == "none" and config.candidates == (PLAIN,)):
        raise UserError("--ablate switches off parameters of the lab's profile; make the first "
                        "--fit train or fold, or give --randomize (and no --sim)")
    if config.ablate and config.arms == ("real",):
        raise UserError("--ablate trains sim-only models; add --arm sim")
    groups = [tuple(sorted(g)) for g in config.ablate]
    if len(set(groups)) != len(groups):
        raise UserError("--ablate: name each group once")
    unknown = [n for group in config.ablate for n in group if n not in PARAMETERS]
    if unknown or any(not group for group in config.ablate):
        raise UserError(f"--ablate {', '.join(unknown) or '(empty)'}: name parameters of "
                        f"{', '.join(PARAMETERS)}, comma-separated")
    return pooled


def _collect(config: Config, out: Path, progress: Progress, randomize: str | None) -> Path:
    """A lab collection in `out` (a `collect` run: resumed, and replaced when another config
    made it, its episodes kept)."""
    req = CollectRequest(config.lab, 3, config.sim_minutes, config.sim_seed, out, "passive",
                         workers=progress.workers, ray=progress.ray, split="80/20/0",
                         overwrite=True, episode_minutes=config.episode_minutes,
                         randomize=randomize)
    if not finished(req):
        collect(req, lambda _, minutes, resumed: progress.report(
            f"lab data {out.name}", minutes, config.sim_minutes, resumed))
    return out


def _drawn_lab(config: Config, profile: dict, kind: str, out: Path, progress: Progress
               ) -> Path:
    """A lab collection drawn from `profile`, in `out / "data"` under a folder named by the
    profile (runs and folds that draw the same share it), the profile written beside it."""
    folder = out / "data" / f"{kind}-{task_key('sim2real-lab', 1, profile)[:12]}"
    folder.mkdir(parents=True, exist_ok=True)
    path = folder.parent / f"{folder.name}.profile.json"
    write_json_atomic(path, profile)
    return _collect(config, folder, progress, str(path) if profile else None)


def _ranges(randomize: str) -> dict | None:
    """A `randomize` candidate's ranges (None for `PLAIN`)."""
    from collectors.randomize import Randomization

    return None if randomize == PLAIN else Randomization.parse(randomize).profile()


def _fitted_lab(config: Config, train: np.ndarray, val: np.ndarray, out: Path, name: str,
                progress: Progress) -> tuple[dict[str, Path], dict]:
    """`sysid` on real poses `train` (checked on `val`), then per `randomize` candidate a lab
    collection drawn around the fitted factors (its ranges times each factor) in
    `out / "data"`. The candidates' collections of the fit are cached in `out / "sysid"`,
    shared by every fit of the run."""
    from collectors.randomize import around
    from macrostate_mj.app.usecases.sysid import SysidConfig, fit

    cfg = SysidConfig(scenario=config.lab, robots=3, minutes=config.sysid_minutes,
                      seed=config.sim_seed, first=config.sysid_first,
                      refine=config.sysid_refine, episode_minutes=config.episode_minutes,
                      workers=progress.workers)
    report = fit(cfg, train, val, out / "sysid",
                 lambda done, total: progress.report(f"sysid {name}", done, total))
    folders = {}
    for randomize in config.candidates:
        # folds whose fits agree share one collection
        folders[randomize] = _drawn_lab(config, around(report["fitted"], _ranges(randomize)),
                                        "fit", out, progress)
    names = {r: f.name for r, f in folders.items()}
    summary = {"fitted": report["fitted"], "train_ks": report["train"],
               "val_ks": report["val"],
               "data": next(iter(names.values())) if len(names) == 1 else names}
    return folders, summary


def lab_data(config: Config, fit: str, pooled: np.ndarray, folds: list[tuple], out: Path,
             progress: Progress) -> tuple[dict[str, list[Path]], dict]:
    """Per `randomize` candidate, each model seed's lab collection (Train.csv and Val.csv),
    and the fits made, by `fit`: `--sim`, or one collection for every seed (the scenario as
    written, or fitted on the real Train.csv), or one per fold fitted on that fold's training
    blocks only."""
    if config.sim is not None:
        return {PLAIN: [config.sim] * len(folds)}, {}
    if fit == "none":
        several = len(config.randomize) > 1
        return {r: [_collect(config, out / "data" / (
            f"sim-{task_key('sim2real-lab', 1, r)[:12]}" if several else "sim"), progress,
            None if r == PLAIN else r)] * len(folds)
            for r in config.candidates}, {}
    if fit == "train":
        from macrostate_mj.app.usecases.sysid import split_check

        n_train = len(read_csv(config.real / REAL_FILES[0]).poses)
        train, check = split_check(pooled) if config.train_only else (
            pooled[:n_train], pooled[n_train:])      # checked on Train's end, or on Val
        folders, fitted = _fitted_lab(config, train, check, out, "train", progress)
        return {r: [f] * len(folds) for r, f in folders.items()}, {"train": fitted}
    made: dict[int, tuple[dict[str, Path], dict]] = {}
    for fold, pool, val in folds:
        if fold not in made:
            made[fold] = _fitted_lab(config, pooled[pool], pooled[val], out, f"fold{fold}",
                                     progress)
    return {r: [made[fold][0][r] for fold, _, _ in folds] for r in config.candidates
            }, {f"fold{f}": fitted for f, (_, fitted) in sorted(made.items())}



def _profile(config: Config, lab: Path, randomize: str) -> dict:
    """The profile a lab collection was drawn from: the one written beside a fitted lab, or
    the `randomize` candidate's."""
    if config.fits[0] != "none":
        return json.loads((lab.parent / f"{lab.name}.profile.json").read_text())
    return _ranges(randomize) or {}


def ablated_labs(config: Config, group: tuple[str, ...], labs: dict, chosen: dict,
                  out: Path, progress: Progress) -> list[Path | None]:
    """Each seed's lab collection with `group` switched off in the profile its sim model was
    chosen with (seeds whose profiles agree share one collection); None for a seed whose
    profile holds none of the group (nothing to switch off). The ablated lab draws its other
    parameters afresh: an episode's draws come in the profile's order, one per range."""
    folders: list[Path | None] = []
    for i in range(config.seeds):
        pick = chosen.get((config.fits[0], config.seed + i))
        ranges = pick["randomize"] if pick else config.candidates[0]
        lab = labs[config.fits[0]][ranges][i]
        own = _profile(config, lab, ranges)
        if not set(group) & set(own):
            folders.append(None)
            continue
        profile = {k: v for k, v in own.items() if k not in group}
        folders.append(_drawn_lab(config, profile, "ablate", out, progress))
    return folders


