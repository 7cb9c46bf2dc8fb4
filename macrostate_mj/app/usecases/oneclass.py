"""`flow`, `oc train` and `oc evaluate` as use cases: each checks its inputs, opens its run in
its output folder (a manifest beside the outputs) and returns what the command prints."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from macrostate_mj.core.errors import UserError
from macrostate_mj.core.io import check_writable_dir, check_writable_file, write_json_atomic
from macrostate_mj.core.run import Run

MIN_AUC_SAMPLES = 2     # fewer and the AUC is 0, 1 or undefined
FEW_AUC_SAMPLES = 30    # fewer and one sample moves the AUC by several hundredths


def flow(out: Path, video: Path | None, frames: Path | None, every: float, gap: float, m: int,
         method: str, label: str | None, start_id: int, crop: tuple[int, ...] | None,
         fps: float | None, overwrite: bool) -> tuple[Path, list[int]]:
    """Optical-flow samples of a video or a frame folder written into `out` (or its `label`
    folder); that folder and the sample ids. Samples are added by id: a later call may add
    another label or more ids to the same dataset."""
    from macrostate_mj.core.progress import LoggedProgress
    from macrostate_mj.formats.hsants import SAMPLE_NAME
    from macrostate_mj.vision.flow import (
        FlowComputer,
        extract_flow_samples,
        read_frame_folder,
        read_video_frames,
    )

    if (video is None) == (frames is None):
        raise UserError("give exactly one of --video FILE or --frames DIR")
    FlowComputer(method)  # fail on a bad --method before reading anything
    target = out / label if label else out
    check_writable_dir(out, create=False)
    if target.is_dir() and not overwrite:
        taken = [p.name for p in target.iterdir()
                 if (hit := SAMPLE_NAME.match(p.name)) and int(hit.group(1)) >= start_id]
        if taken:
            raise UserError(f"{target / sorted(taken)[0]} already exists; pass --overwrite or a "
                            "larger --start-id")
    config = {"video": video, "frames": frames, "every": every, "gap": gap, "m": m,
              "method": method, "label": label, "start_id": start_id, "crop": crop, "fps": fps}
    with Run(target, "flow", config, None, overwrite=True) as run:
        stream, rate = (read_video_frames(video, fps) if video
                        else read_frame_folder(frames, fps))
        with LoggedProgress(transient=True) as bar:
            task = bar.add_task("reading frames", total=None)

            def counted():
                for f in stream:
                    bar.advance(task)
                    yield f

            ids = extract_flow_samples(counted(), rate, out, every=every, gap=gap, m=m,
                                       method=method, label=label, start_id=start_id, crop=crop)
        run.record(fps=rate, samples=[ids[0], ids[-1]], n_samples=len(ids))
    return target, ids


def train(data: Path, out: Path, methods: tuple[str, ...], cfg: Any, split: int, recipe: str,
          overwrite: bool, tick: Callable[..., None]) -> int:
    """One-class models trained on a split's stable train samples only (model selection on
    held-out stable data), saved in `out`, its stages resumable in `out/stages`; the number
    of training samples."""
    from estimators.oneclass import fit
    from macrostate_mj.formats.hsants import open_dataset

    config = {"oc": cfg, "methods": list(methods), "data": data, "split": split,
              "recipe": recipe}
    with Run(out, "oc train", config, cfg.seed, ["weights.pt", "model.json"], overwrite) as run:
        d = open_dataset(data)
        train_ids, _ = d.split(split)
        x = d.load("Stable", train_ids, cfg.m)
        with run.stage("train"):
            model = fit(x, methods, cfg, tick, stages_dir=out / "stages")
        model.save(out)
        run.record(n_train=len(x), resumed_stages=model.resumed)
    return len(x)


def evaluate(model: Path, data: Path, out: Path, split: int, method: str | None,
             unstable: Path | None, baseline: str | None, intervals: bool, overwrite: bool,
             note: Callable[[str], None]) -> dict:
    """AUC of a split's stable test samples against the unstable ones (unstable = positive),
    overall and per time bin, with bootstrap intervals and, against a baseline, paired
    p-values; the report written to `out`, its manifest beside it. `note` hears a warning."""
    from estimators.oneclass import OCModel
    from estimators.oneclass.metrics import auc_report, interval_report, paired_report
    from macrostate_mj.formats.hsants import open_dataset

    check_writable_file(out, overwrite, "--out")
    oc = OCModel.load(model)
    meth = method or oc.methods[-1]
    for name in (meth, baseline):
        if name is not None and name not in oc.methods:
            raise UserError(f"{model} holds {', '.join(oc.methods)}, not {name}; train it with "
                            f"`oc train --method {name}` or choose another")
    d = open_dataset(data)
    if unstable is not None:
        d = d.with_unstable(unstable)
    _, test = d.split(split)
    m = oc.channels // 2
    n_unstable = len(d.unstable_ids)
    if min(len(test), n_unstable) < MIN_AUC_SAMPLES:
        raise UserError(f"split {split} has {len(test)} stable test and {n_unstable} unstable "
                        f"samples; an AUC needs at least {MIN_AUC_SAMPLES} of each")
    if min(len(test), n_unstable) < FEW_AUC_SAMPLES:
        note(f"note: an AUC from {len(test)} stable and {n_unstable} unstable samples is a "
             "smoke test, not a measurement")
    config = {"model": str(model), "data": str(data), "split": split, "method": meth,
              "unstable": None if unstable is None else str(unstable), "baseline": baseline,
              "intervals": intervals}
    # the report was checked writable above, so the run claims the folder as is
    with Run(out.parent, "oc evaluate", config, None, [out.name], overwrite=True,
             manifest=out.name + ".manifest.json") as run, run.stage("evaluate"):
        x_stable, x_unstable = d.load("Stable", test, m), d.load("Unstable", d.unstable_ids, m)
        s_stable, s_unstable = oc.score(meth, x_stable), oc.score(meth, x_unstable)
        bins, names = d.time_bin(d.unstable_ids), tuple(d.bins)
        report = auc_report(s_stable, s_unstable, bins, names)
        if intervals:
            report["auc_ci95"] = interval_report(s_stable, s_unstable, bins, names)
        if baseline is not None:
            report["vs_baseline"] = {"baseline": baseline, **paired_report(
                s_stable, s_unstable, oc.score(baseline, x_stable),
                oc.score(baseline, x_unstable), bins, names)}
        report.update(method=meth, split=split, m=m, model=str(model), data=str(data),
                      unstable=str(unstable or d.root / "Unstable"))
        write_json_atomic(out, report)
    return report
