"""`flow`, `oc train|evaluate`, `experiment oc`: optical flows and one-class models (ch. 4)."""

from __future__ import annotations

import os
import time
from pathlib import Path
from typing import Annotated

import typer

from macrostate_mj.app.cli.app import app, experiment_app, oc_app
from macrostate_mj.core.errors import UserError
from macrostate_mj.core.progress import stage_progress

Opt = typer.Option
METHODS = ("ofw", "dcae", "ocsvm", "dsvdd", "gen", "ngen", "iogen")


def _choice(value: str, choices: tuple[str, ...], flag: str) -> str:
    if value not in choices:
        raise UserError(f"{flag} {value!r} is not one of {', '.join(choices)}")
    return value


def _crop(text: str | None) -> tuple[int, int, int, int] | None:
    if text is None:
        return None
    try:
        x, y, w, h = (int(v) for v in text.split(","))
    except ValueError:
        raise UserError(f"--crop {text!r} must be four integers x,y,w,h") from None
    return x, y, w, h


def _default_threads() -> int:
    return min(2, os.cpu_count() or 1)


@app.command("flow")
def flow(
    out: Annotated[Path, Opt(help="Dataset folder to write (OpticalFlows_HsAnts layout).")],
    video: Annotated[Path | None, Opt(help="Any OpenCV-readable video file.")] = None,
    frames: Annotated[Path | None, Opt(help="Folder of frames (natural name order).")] = None,
    every: Annotated[float, Opt(help="Seconds between samples (the seed: 120).")] = 120.0,
    gap: Annotated[float, Opt(help="Seconds between the two frames of a pair.")] = 0.5,
    m: Annotated[int, Opt(help="Consecutive flow pairs per sample.")] = 4,
    method: Annotated[str, Opt(help="dis (default), farneback or tvl1 (opencv-contrib).")] = "dis",
    label: Annotated[str | None, Opt(help="Write into OUT/Stable or OUT/Unstable.")] = None,
    start_id: Annotated[int, Opt(help="Id of the first sample written.")] = 0,
    crop: Annotated[str | None, Opt(help="Crop x,y,w,h (px) before the flow.")] = None,
    fps: Annotated[float | None, Opt(help="Frame rate (required with --frames).")] = None,
    overwrite: Annotated[bool, Opt("--overwrite", help="Replace samples already there.")] = False,
) -> None:
    """Video or frames -> optical-flow samples (flow_x/flow_y/img JPEGs, 64 × 64, 128 = still)."""
    if (video is None) == (frames is None):
        raise UserError("give exactly one of --video FILE or --frames DIR")
    if label is not None:
        _choice(label, ("Stable", "Unstable"), "--label")
    box = _crop(crop)
    from macrostate_mj.core.io import check_writable_dir, write_manifest
    from macrostate_mj.formats.hsants import SAMPLE_NAME
    from macrostate_mj.vision.flow import (
        FlowComputer,
        extract_flow_samples,
        read_frame_folder,
        read_video_frames,
    )

    FlowComputer(method)  # fail on a bad --method before reading anything
    target = out / label if label else out
    check_writable_dir(out, create=False)
    if target.is_dir() and not overwrite:
        taken = [p.name for p in target.iterdir()
                 if (hit := SAMPLE_NAME.match(p.name)) and
                 int(hit.group(1)) >= start_id]
        if taken:
            raise UserError(f"{target / sorted(taken)[0]} already exists; pass --overwrite or a "
                            "larger --start-id")
    t0 = time.perf_counter()
    stream, rate = read_video_frames(video, fps) if video else read_frame_folder(frames, fps)
    from macrostate_mj.core.progress import LoggedProgress

    with LoggedProgress(transient=True) as bar:
        task = bar.add_task("reading frames", total=None)

        def counted():
            for f in stream:
                bar.advance(task)
                yield f

        ids = extract_flow_samples(counted(), rate, out, every=every, gap=gap, m=m, method=method,
                                   label=label, start_id=start_id, crop=box)
    config = {"video": video, "frames": frames, "every": every, "gap": gap, "m": m,
              "method": method, "label": label, "start_id": start_id, "crop": box, "fps": rate}
    write_manifest(target, "flow", config, None, {"total": time.perf_counter() - t0},
                   samples=[ids[0], ids[-1]], n_samples=len(ids))
    typer.echo(f"wrote {len(ids)} samples ({ids[0]:05d}..{ids[-1]:05d}) to {target}")


@oc_app.command("train")
def oc_train(
    method: Annotated[str, Opt(help=f"One of {', '.join(METHODS)}, or all.")],
    data: Annotated[Path, Opt(help="Dataset folder (Stable/, Unstable/, split1..3/).")],
    out: Annotated[Path, Opt(help="Model folder to write.")],
    split: Annotated[int, Opt(help="Split 1..3 (its stable train list is the training set).")] = 1,
    m: Annotated[int, Opt(help="Flow pairs per input.")] = 2,
    seed: Annotated[int, Opt(help="Seed of every random draw.")] = 0,
    epochs: Annotated[float, Opt(help="Scale every epoch/step count (0.05 = quick).")] = 1.0,
    threads: Annotated[int, Opt(help="torch CPU threads (results repeat for equal threads).")]
    = _default_threads(),
    device: Annotated[str, Opt(help="cpu or cuda.")] = "cpu",
    overwrite: Annotated[bool, Opt("--overwrite", help="Replace an earlier model.")] = False,
) -> None:
    """Train a one-class model on stable samples only; model selection on held-out stable data."""
    methods = tuple(METHODS) if method == "all" else (_choice(method, METHODS, "--method"),)
    _choice(device, ("cpu", "cuda"), "--device")
    if epochs <= 0 or threads < 1:
        raise UserError("--epochs must be > 0 and --threads >= 1")
    from macrostate_mj.core.io import prepare_out_dir, write_manifest

    prepare_out_dir(out, ["weights.pt", "model.json"], overwrite)
    import torch

    from estimators.oneclass import OCConfig, fit
    from macrostate_mj.formats.hsants import open_dataset

    if device == "cuda" and not torch.cuda.is_available():
        raise UserError("--device cuda but torch sees no GPU; use --device cpu")
    d = open_dataset(data)
    train, _ = d.split(split)
    x = d.load("Stable", train, m)
    cfg = OCConfig(m=m, seed=seed, threads=threads, device=device).scaled(epochs)
    t0 = time.perf_counter()
    with stage_progress() as tick:
        model = fit(x, methods, cfg, tick)
    out.mkdir(parents=True, exist_ok=True)
    model.save(out)
    write_manifest(out, "oc train", cfg, seed, {"train": time.perf_counter() - t0},
                   methods=list(methods), data=data, split=split, n_train=len(x))
    typer.echo(f"trained {', '.join(methods)} on {len(x)} stable samples -> {out}")


@oc_app.command("evaluate")
def oc_evaluate(
    model: Annotated[Path, Opt(help="Model folder from `oc train`.")],
    data: Annotated[Path, Opt(help="Dataset folder.")],
    out: Annotated[Path, Opt(help="Report JSON to write.")],
    split: Annotated[int, Opt(help="Split whose stable test list is scored.")] = 1,
    method: Annotated[str | None, Opt(help="Method to score (default: the model's last).")]
    = None,
    overwrite: Annotated[bool, Opt("--overwrite", help="Replace an earlier report.")] = False,
) -> None:
    """AUC of stable test vs unstable samples (unstable = positive), overall and per time bin."""
    from macrostate_mj.core.io import check_writable_file, write_json_atomic

    check_writable_file(out, overwrite, "--out")
    from estimators.oneclass import OCModel
    from estimators.oneclass.metrics import auc_report
    from macrostate_mj.formats.hsants import open_dataset

    oc = OCModel.load(model)
    meth = method or oc.methods[-1]
    d = open_dataset(data)
    _, test = d.split(split)
    m = oc.channels // 2
    report = auc_report(oc.score(meth, d.load("Stable", test, m)),
                        oc.score(meth, d.load("Unstable", d.unstable_ids, m)),
                        d.time_bin(d.unstable_ids), tuple(d.bins))
    report.update(method=meth, split=split, m=m, model=str(model), data=str(data))
    write_json_atomic(out, report)
    bins = ", ".join(f"{k} {v:.3f}" for k, v in report["auc_bins"].items() if v is not None)
    typer.echo(f"{meth}: AUC {report['auc_all']:.3f} ({bins}) -> {out}")


@experiment_app.command("oc")
def experiment_oc(
    data: Annotated[Path, Opt(help="Dataset folder (real or simulated).")],
    out: Annotated[Path, Opt(help="Folder for tables, figures, Grad-CAM and results.json.")],
    splits: Annotated[str, Opt(help="Comma-separated splits.")] = "1,2,3",
    ms: Annotated[str, Opt(help="Comma-separated m values (Table 4.1).")] = "1,2,4",
    seed: Annotated[int, Opt(help="Seed of every random draw.")] = 0,
    epochs: Annotated[float, Opt(help="Scale every epoch/step count.")] = 1.0,
    quick: Annotated[bool, Opt("--quick", help="Smoke run: epochs x0.03, 200 train samples.")]
    = False,
    threads: Annotated[int, Opt(help="torch CPU threads.")] = _default_threads(),
    overwrite: Annotated[bool, Opt("--overwrite", help="Replace earlier outputs.")] = False,
) -> None:
    """Reproduce Table 4.1, Table 4.2, Fig 4.7–4.10 and Grad-CAM overlays (mean ± std)."""
    try:
        split_list = tuple(int(s) for s in splits.split(","))
        m_list = tuple(int(s) for s in ms.split(","))
    except ValueError:
        raise UserError("--splits and --ms take comma-separated integers, e.g. 1,2,3") from None
    if epochs <= 0 or threads < 1:
        raise UserError("--epochs must be > 0 and --threads >= 1")
    from estimators.oneclass.train import OCConfig
    from macrostate_mj.app.experiments.oneclass import PRODUCTS, OCExperiment, run_experiment
    from macrostate_mj.core.io import prepare_out_dir, write_json_atomic, write_manifest
    from macrostate_mj.formats.hsants import open_dataset

    prepare_out_dir(out, PRODUCTS, overwrite)
    d = open_dataset(data)
    for k in split_list:
        d.split(k)
    for m in m_list:
        if not 1 <= m <= d.subframes:
            raise UserError(f"--ms has m = {m} but {data} has {d.subframes} sub-frames per sample")
    cfg = OCConfig(seed=seed, threads=threads).scaled(epochs * (0.03 if quick else 1.0))
    exp = OCExperiment(data, split_list, m_list, cfg, 200 if quick else None)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    with stage_progress() as tick:
        results = run_experiment(exp, out, tick)
    write_json_atomic(out / "results.json", results)
    write_manifest(out, "experiment oc", exp, seed, {"total": time.perf_counter() - t0})
    typer.echo((out / "tables.md").read_text())
