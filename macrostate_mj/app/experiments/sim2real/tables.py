"""`experiment sim2real`'s tables and numbers as the docs show them, read through its record."""

from __future__ import annotations

import statistics
from pathlib import Path

from macrostate_mj.app.experiments.sim2real.config import TUNED, Config
from macrostate_mj.app.experiments.sim2real.record import Results
from macrostate_mj.app.results.sources import paired, paired_of, record, source, stat
from macrostate_mj.core.evidence import Code, Table


@source
def s2r(folder: str) -> Table:
    """Sim-to-real: each arm's real-test Head error (cm) by share of the real pool."""
    arms = record(Results, folder).arms
    fractions = sorted({f for arm in arms.values() for f in arm}, key=float)
    rows = [["arm", *[f"{float(f) * 100:.0f} % real" for f in fractions]]]
    for arm, by_fraction in arms.items():
        cells = []
        for f in fractions:
            ms = by_fraction.get(f, {}).get("head_cm")
            cells.append(f"{ms['mean']:.2f} ± {ms['std']:.2f}" if ms else "")
        rows.append([arm, *cells])
    return rows


@source
def s2r_pairs(base: str, other: str) -> Table:
    """Two sim-to-real runs of the same arms, folds and seeds: per arm and share of the real
    pool the Head error (cm) of each, mean ± std over seeds, and the difference (other - base):
    paired over the seeds with its 95 % interval, or of the means where a run kept no seed's
    (older runs)."""
    a, b = (record(Results, f).arms for f in (base, other))
    rows = [["arm", "% real", base, other, "difference"]]
    for arm, by_fraction in a.items():
        for f in sorted(by_fraction, key=float):
            mine, theirs = by_fraction[f], b.get(arm, {}).get(f)
            if not theirs:
                continue
            x, y = mine["head_cm"], theirs["head_cm"]
            diff = f"{y['mean'] - x['mean']:+.2f}"
            if "head_cm_by_seed" in mine and "head_cm_by_seed" in theirs:
                seeds = mine["head_cm_by_seed"]
                diff = str(paired_of({s: theirs["head_cm_by_seed"][s] - v
                                      for s, v in seeds.items()}, [base, other]))
            rows.append([arm, f"{float(f) * 100:.0f}", stat(x, ".2f"), stat(y, ".2f"), diff])
    return rows


@source
def s2r_sim(real: str, *folders: str) -> Table:
    """Sim-only runs (`experiment sim2real --arm sim`) on different lab data: each one's
    real-fold Head error, its ratio to `real`'s real-only arm on all of the pool (the same
    folds and seeds), on how many folds it beats the first run, and its difference from the
    first paired over the seeds (95 % interval). A run's minutes of lab data and its
    checkpoints' choice are named where they are not the command's defaults."""
    plain = Config()
    full = record(Results, real).arms["real"]["1"]["head_cm"]["mean"]
    rows = [["lab data (--randomize)", "sim only, Head (cm)", "÷ real only (100 %)",
             "folds better than the first", "minus the first (cm)"]]
    runs = [record(Results, folder) for folder in folders]
    first = runs[0].arms["sim"]["0"]["head_cm_by_seed"]
    for i, run in enumerate(runs):
        profile, cell = run.profile, run.arms["sim"]["0"]
        ms, by_seed = cell["head_cm"], cell["head_cm_by_seed"]
        better = sum(by_seed[s] < first[s] for s in first)
        names = profile["randomize"]
        names = [names] if isinstance(names, str) else names or []   # older runs: one
        how = [f"{profile['sim_minutes']:g} min"] \
            if profile.get("sim_minutes", plain.sim_minutes) != plain.sim_minutes else []
        if profile.get("sim_select", plain.sim_select) != plain.sim_select:
            how.append("checkpoint on the real validation block")
        label = Code(" or ".join(Path(p).name for p in names) or "none",
                     f" ({', '.join(how)})" if how else "")
        rows.append([label, f"{ms['mean']:.2f} ± {ms['std']:.2f}", f"{ms['mean'] / full:.2f}x",
                     f"{better} / {len(first)}" if i else "",
                     str(paired_of({s: by_seed[s] - first[s] for s in first},
                                   [folders[0], folders[i]])) if i else ""])
    return rows


FIT_LABELS = {"none": "none: the scenario as written",
              "fold": "fold: fitted in each fold on its training blocks (nested)",
              "train": "train: fitted on the real Train.csv (has seen the test blocks)"}


@source
def s2r_fits(folder: str) -> Table:
    """A sim-to-real run's sim-only models by where the lab's factors came from (`--fit`), on
    the same folds and seeds: Head error (cm), its ratio to the real-only arm on all of the
    pool, and the per-seed difference to the first fit's (mean ± std over seeds)."""
    fits = record(Results, folder).sim_by_fit
    assert fits is not None
    first = next(iter(fits.values()))["head_cm_by_seed"]
    rows = [["lab factors (--fit)", "sim only, Head (cm)", "÷ real only (100 %)",
             "− the first, per seed (cm)"]]
    for i, (fit, cell) in enumerate(fits.items()):
        diffs = [cell["head_cm_by_seed"][s] - first[s] for s in first]
        rows.append([FIT_LABELS.get(fit, fit), stat(cell["head_cm"], ".2f"),
                     f"{cell['sim_over_real']:.2f}x" if "sim_over_real" in cell else "",
                     f"{statistics.fmean(diffs):+.2f} ± {statistics.stdev(diffs):.2f}"
                     if i and len(diffs) > 1 else ""])
    return rows


@source
def s2r_fit_runs(fit: str, *folders: str) -> Table:
    """One `--fit` of several sim-to-real runs on the same folds and seeds (different lab
    models): how many parameters it fitted, its sim-only Head error, its ratio to the run's
    real-only arm, and on how many folds it beats the first run's."""
    rows = [["run", "parameters fitted", "sim only, Head (cm)", "÷ real only (100 %)",
             "folds better than the first"]]
    first: dict = {}
    for i, folder in enumerate(folders):
        data = record(Results, folder)
        cell = (data.sim_by_fit or {}).get(fit) or data.arms["sim"]["0"]
        fitted = next(v["fitted"] for k, v in (data.fits or {}).items() if k.startswith(fit))
        real = data.arms["real"]["1"]["head_cm"]["mean"]
        by_seed = cell["head_cm_by_seed"]
        first = first or by_seed
        better = sum(by_seed[s] < first[s] for s in first)
        rows.append([Code(folder), str(len(fitted)), stat(cell["head_cm"], ".2f"),
                     f"{cell['head_cm']['mean'] / real:.2f}x",
                     f"{better} / {len(first)}" if i else ""])
    return rows


@source
def s2r_ranges(folder: str) -> Table:
    """The `--randomize` candidates of a sim-to-real run, chosen per fold on its real
    validation block: each candidate's Head error there and on the test blocks (mean ± std
    over the seeds) and on how many folds it was chosen."""
    ranges_ = record(Results, folder).ranges or {}
    rows = [["fit", "ranges (--randomize)", "validation block, Head (cm)", "test block, Head (cm)",
             "chosen on"]]
    for fit, ranges in ranges_.items():
        chosen = list(ranges["chosen_by_seed"].values())
        for name, cell in ranges["candidates"].items():
            rows.append([fit, Code(Path(name).name),
                         stat(cell["select_head_cm"], ".2f"), stat(cell["head_cm"], ".2f"),
                         f"{chosen.count(name)} / {len(chosen)}"])
    return rows


def _tuned(folder: str, tuned: str, setting: str) -> Table:
    """A setting chosen per seed and real share on the real validation block (the `sim2real`
    `Tuned` named `tuned`): each candidate's error there and on the test blocks (mean ± std
    over the seeds) and for how many seeds it was kept."""
    table, cells = next((t.table, t.cells) for t in TUNED if t.name == tuned)
    data = record(Results, folder)
    rows = [["arm", "real data", setting, "validation block, mean error (cm)",
             "test block, Head (cm)", "kept for"]]
    for arm, shares in getattr(data, table).items():
        for share, cell in shares.items():
            kept = [f"{w:g}" for w in cell["chosen_by_seed"].values()]
            for value, w in sorted(cell[cells].items(), key=lambda kv: float(kv[0])):
                rows.append([arm, f"{float(share) * 100:.0f} %", value,
                             stat(w["best_val_cm"], ".2f"), stat(w["head_cm"], ".2f"),
                             f"{kept.count(value)} / {len(kept)}"])
    return rows


@source
def s2r_mixes(folder: str) -> Table:
    """The mixing arms' lab shares (`--mix-weight`), chosen per seed and real share on the real
    validation block (see `_tuned`)."""
    return _tuned(folder, "mix_weight", "lab share of the loss")


@source
def s2r_finetunes(folder: str) -> Table:
    """The fine-tuned arms' epochs (`--finetune-epochs`), chosen per seed and real share on the
    real validation block (see `_tuned`)."""
    return _tuned(folder, "finetune_epochs", "fine-tuning epochs")


@source
def s2r_ablations(folder: str) -> Table:
    """Each group of lab parameters switched off (`--ablate`): the sim-only Head error and
    its difference to the lab's own on the same seeds, with the 95 % interval over the run's
    units (`Paired.of`: its folds, corrected; the run's own `minus_lab` is over seeds)."""
    data = record(Results, folder)
    lab = data.arms["sim"]["0"]["head_cm_by_seed"]
    rows = [["switched off", "sim only, Head (cm)", "minus the lab's (cm)", "95 % interval"]]
    for group, cell in (data.ablations or {}).items():
        d = paired_of({s: v - lab[s] for s, v in cell["head_cm_by_seed"].items()}, [folder])
        rows.append([Code(group), stat(cell["head_cm"], ".2f"),
                     f"{d.mean:+.2f}", f"[{d.low:+.2f}, {d.high:+.2f}], {d.units}"])
    return rows


def _excesses(folder: str) -> tuple[float, float, float]:
    """One sim-to-real run's sim only and fine-tuned-on-a-quarter Head errors minus real only
    on all of the pool, each paired over its seeds (`paired`'s mean), and real only's mean
    (cm)."""
    path, real = f"{folder}/results.json", "arms/real/1/head_cm_by_seed"
    return (paired(path, "arms/sim/0/head_cm_by_seed", real).mean,
            paired(path, "arms/finetune/0.25/head_cm_by_seed", real).mean,
            statistics.fmean(record(Results, folder).arms["real"]["1"]["head_cm_by_seed"].values()))


@source
def s2r_transfer(*folders: str) -> Table:
    """Sim-to-real runs of different lab data: each one's sim-only excess over real only (all
    of the pool) beside its fine-tuned-on-a-quarter excess, both paired over its seeds."""
    rows = [["run", "sim only minus real only (cm)", "sim ÷ real", "fine-tuned on 25 % minus "
             "real only (cm)"]]
    for folder in folders:
        sim, tuned, real = _excesses(folder)
        rows.append([Code(folder), f"{sim:+.2f}", f"{(real + sim) / real:.2f}x",
                     f"{tuned:+.2f}"])
    return rows

