"""`experiment sim2real`: how far lab data carries a ReTLo model on real data, and how much real
data sim pre-training saves (a data-efficiency curve).

Real data: a folder of ThymioLoc 3-robot files, `Train.csv` then `Val.csv`, pooled in that order
and cut into `folds` contiguous blocks (instances overlap in time, so a random split would leak);
with `train_only`, Train.csv alone, Val.csv left sealed for `experiment s2r-sealed`.
Model i (seed `seed + i`) is tested on block i mod `folds`, never used by any model of that
seed; of the other blocks, the last `val_share` selects the real-trained checkpoints and the rest
is the real training pool, of which 10 / 25 / 50 / 100 % are used (contiguous parts in turn
over the seeds: `share`). Four arms per seed
(`arms` picks some: `sim` alone asks only how far a lab collection carries):
- sim: trained and selected on a lab collection only (`collect --scenario SCENARIO --robots 3
  --split 80/20/0 [--randomize PROFILE]`, a `collect` run in `data/sim`, or `--sim DIR` with
  Train.csv and Val.csv); with `sim_select` "real", trained on it and selected on the fold's
  real validation block;
- real: trained on a fraction of the pool, selected on the real validation block;
- finetune: the same seed's sim model trained further on the same fraction (`finetune_epochs`;
  name several and each seed and fraction keeps the one best on the real validation block);
- mixed: trained on the same fraction and the lab Train.csv together (`mix_weight`; name
  several and each seed and fraction keeps the one best on the real validation block);
- finetune-mixed: the seed's sim model trained further on the same fraction with the lab
  Train.csv mixed in, as the mixed arm mixes it (pre-trained on the lab, then fine-tuned
  without forgetting it);
- finetune-frozen: as finetune, with the sim model's observation and history encoders kept
  fixed (`train retlo --freeze-encoder`): fewer weights for a small real share to move.
Where the lab's factors come from (`fits`, `--fit`): the scenario as written; a `sysid` fit on
the real Train.csv (leaky under these folds, whose test blocks it has seen); or the nested
protocol, one fit per fold on that fold's training and validation blocks alone, so the
cross-validated ratio estimates what a held-out real test will show. Naming several trains
each one's sim-only models on the same folds (`sim_by_fit`). The randomization ranges drawn
around the factors (`randomize`, `--randomize`) can be chosen inside each fold as well: name
several candidates (`none` for no ranges) and each seed's sim model is the candidate's whose
Head error on that fold's real validation block is lowest (`ranges`); the test block never
takes part. What each modelled difference is worth (`ablate`, `--ablate`): per seed, a lab
collected from that seed's own profile with the named parameters switched off (their factor 1,
or their value 0) trains one more sim-only model; its Head error minus the lab's, paired by
seed, averaged to the folds, with a 95 % interval over them (`ablations`).
Every model is the LSTM of `train retlo --model lstm`, a cached task
(`cache/sim2real-model/<key>/`: its report, and a sim model's checkpoint) keyed by its training
settings and the bytes of its data (the lab CSVs, the real blocks, a fine-tuned model's sim
checkpoint): a rerun after a kill trains only what is missing, and new inputs (a refit lab, other
real files) train new models instead of mixing with the old.
"""

from __future__ import annotations

import json
from pathlib import Path

from macrostate_mj.app.experiments import Progress, register
from macrostate_mj.app.experiments.sim2real.config import (
    ARMS,
    FINETUNED,
    FLAGS,
    PARALLEL,
    PRODUCTS,
    PROFILES,
    REAL_DATA,
    TUNED,
    Config,
    configure,
    missing,
)
from macrostate_mj.app.experiments.sim2real.data import ablated_labs, lab_data, read_real, validate
from macrostate_mj.app.experiments.sim2real.models import (
    ModelTask,
    arm_task,
    best_by,
    candidates,
    choose_settings,
    fold_of,
    share,
    sim_task,
    train_models,
)
from macrostate_mj.app.experiments.sim2real.record import Results
from macrostate_mj.app.experiments.sim2real.report import (
    by_ablation,
    by_fit,
    by_range,
    equivalent_fraction,
    summarize,
    summary_lines,
)
from macrostate_mj.core.stats import cv_blocks
from macrostate_mj.formats.thymioloc import DEFAULT_PX_PER_CM

__all__ = ["FLAGS", "PARALLEL", "PRODUCTS", "PROFILES", "REAL_DATA", "TUNED", "Config", "ModelTask",
           "Results", "arm_task", "candidates", "configure", "equivalent_fraction", "fold_of",
           "missing", "read_real", "share", "sim_task", "train_models", "validate"]


@register
def run(config: Config, out: Path, progress: Progress) -> list[str]:
    """Collect (or take) the lab data, train every arm and fraction, plot; summary lines."""
    from estimators.retlo.files import pixels_to_world
    from viz.sim2real_figures import plot_curve

    with progress.stage("data"):
        pixels = validate(config)
        held = [fold_of(i, config.folds) for i in range(config.seeds)]
        folds = [(f, *cv_blocks(len(pixels), config.folds, f, config.val_share)[:2])
                 for f in held]
        labs, fits = {}, {}
        for fit in config.fits if config.arms != ("real",) else ():
            labs[fit], made = lab_data(config, fit, pixels, folds, out, progress)
            fits |= made
    pooled = pixels_to_world(pixels, DEFAULT_PX_PER_CM)
    later = [a for a in ARMS[1:] if a in config.arms]
    choose = len(config.candidates) > 1
    # the mixed arm alone trains sim models only to choose its lab data or to ablate it
    sim_models = bool({"sim", *FINETUNED} & set(config.arms)) or choose or \
        bool(config.ablate)
    per_share = sum(len(candidates(config, a)) for a in later)
    total = config.seeds * (sim_models * len(labs) * len(config.candidates)
                            + per_share * len(config.fractions) + len(config.ablate))
    blocks, first = [], []
    for i in range(config.seeds):
        s = config.seed + i
        pool, val, test = cv_blocks(len(pooled), config.folds, fold_of(i, config.folds),
                                    config.val_share)
        blocks.append((s, pooled[pool], pooled[val], pooled[test]))
        if sim_models:
            first += [({"arm": "sim", "fit": fit, "randomize": r, "fraction": 0.0, "count": 0,
                        "seed": s},
                       sim_task(config, s, lab[i], pooled[val], pooled[test], choose))
                      for fit, by_range in labs.items() for r, lab in by_range.items()]
    with progress.stage("models"):
        done = train_models(first, progress, total)
        sims = [{**meta, **json.loads((done[id(task)].folder / "report.json").read_text()),
                 "folder": done[id(task)].folder} for meta, task in first]
        # per fit and seed, the candidate best on the real validation block
        chosen = best_by(sims, lambda r: (r["fit"], r["seed"]), "select_head_cm")
        second: list[tuple[dict, ModelTask]] = []
        for i, (s, pool, val, test) in enumerate(blocks):
            sim = chosen.get((config.fits[0], s))
            ranges = sim["randomize"] if sim else config.candidates[0]
            lab = labs[config.fits[0]][ranges][i] if labs else None
            checkpoint = sim["folder"] / "model.pt" if sim else None
            for f in config.fractions:
                part = share(len(pool), f, i)
                second += [({"arm": arm, "fraction": f, "count": part.stop - part.start, "seed": s,
                             **tuned},
                            arm_task(arm, config, s, pool[part], val, test, checkpoint, lab,
                                      **tuned))
                           for arm in later for tuned in candidates(config, arm)]
        done |= train_models(second, progress, total, done)
        third = [({"ablate": group, "seed": s}, sim_task(config, s, lab, val, test, False))
                 for group in config.ablate
                 for (s, _, val, test), lab in zip(blocks, ablated_labs(
                     config, group, labs, chosen, out, progress), strict=True)
                 if lab is not None]
        done |= train_models(third, progress, total, done)
    reports, choices = choose_settings([
        {**meta, **json.loads((done[id(task)].folder / "report.json").read_text())}
        for meta, task in second], config)
    # the first fit's chosen sim models are the sim arm; the other fits' are kept apart
    picked = [{k: v for k, v in r.items() if k != "folder"} for r in chosen.values()]
    others = [r for r in picked if r["fit"] != config.fits[0]]
    if "sim" in config.arms:
        reports += [r for r in picked if r["fit"] == config.fits[0]]
    results = summarize(reports, config, len(pooled))
    if len(labs) > 1:
        results["sim_by_fit"] = by_fit(reports, others, config, results)
    if choose:
        results["ranges"] = by_range(sims, chosen, config)
    if config.ablate:
        results["ablations"] = by_ablation(
            [{**meta, **json.loads((done[id(task)].folder / "report.json").read_text())}
             for meta, task in third], chosen, config)
    results |= choices
    if fits:
        results["fits"] = fits
    Results.of(results, "experiment sim2real").write(out)
    plot_curve(results, out / "sim2real.png")
    hits = set(progress.cache.hits)
    progress.record(models=len(reports),
                    sim_data=sorted({str(p) for by_range in labs.values()
                                     for lab in by_range.values() for p in lab}),
                    models_trained=len({t.key() for _, t in [*first, *second, *third]}
                                       - hits))
    lines = summary_lines(results)
    if not config.train_only:       # said where the run ends: a sealed file was read
        lines.append("these folds pool Val.csv, the sim-to-real work's sealed test (experiment "
                     "s2r-sealed): choose settings with --train-only, then look once there")
    return lines
