"""`experiment retlo`: Fig 2.7, Fig 2.8 and a Fig 2.9-style video from ThymioLoc files.

Every learned model is trained once per seed on the training files, selected on the validation
file, and tested on every test file whatever its team size (the 3-robot module runs along
longer chains without retraining). The 2X heuristic has no seed. results.json holds only
deterministic numbers (timings go to the manifest), so the same command gives the same file.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from estimators.retlo.api import evaluate, fit
from estimators.retlo.chain import Module, predict_chain
from estimators.retlo.files import read_world, world_to_pixels
from estimators.retlo.heuristic import Heuristic2X
from estimators.retlo.models import ModelConfig, TorchPredictor
from estimators.retlo.train import TrainConfig, load_checkpoint, save_checkpoint
from macrostate_mj.core.errors import UserError
from macrostate_mj.core.io import check_writable_dir, write_json_atomic, write_manifest
from macrostate_mj.formats.thymioloc import DEFAULT_PX_PER_CM

PRODUCTS = ["results.json", "fig2_7.png", "fig2_8.png", "fig2_9.mp4", "models", "manifest.json"]
HEURISTIC = "heuristic2x"
LEARNED = ("fc", "lstm")


def load_predictor(model: str) -> tuple[Module, str]:
    """A `--model` value (a checkpoint path or heuristic2x) → predictor and display name."""
    if model == HEURISTIC:
        return Heuristic2X(), HEURISTIC
    if not model.endswith(".pt") and not Path(model).exists():
        raise UserError(f"unknown model {model!r}; pass a checkpoint .pt from `train retlo` "
                        f"or {HEURISTIC}")
    net, ckpt = load_checkpoint(model)
    return TorchPredictor(net), str(ckpt["kind"])


@dataclass(frozen=True)
class ExperimentConfig:
    """What `experiment retlo` runs; recorded in the manifest."""

    train: list[str]
    val: str
    test: list[str] = field(default_factory=list)
    holdout: float = 0.0  # fraction of each training file held out as a test set
    seeds: int = 5
    epochs: int = 60
    px_per_cm: float = DEFAULT_PX_PER_CM
    video_instances: int = 3
    model: ModelConfig = ModelConfig()   # its kind is set per run; history, LSTM direction, angles

    def validate(self) -> None:
        if self.seeds < 1 or self.epochs < 1:
            raise UserError("--seeds and --epochs must be at least 1")
        if not 0.0 <= self.holdout < 0.9:
            raise UserError(f"--holdout must be in [0, 0.9), got {self.holdout}")
        if not self.test and self.holdout == 0.0:
            raise UserError("no test set; pass --test CSV or --holdout FRACTION")


def _split(world: np.ndarray, fraction: float) -> tuple[np.ndarray, np.ndarray]:
    """(kept, held out) instances; a fixed seed so every run holds out the same ones."""
    order = np.random.default_rng(0).permutation(len(world))
    n_out = int(round(fraction * len(world)))
    if fraction and not 0 < n_out < len(world):
        raise UserError(f"--holdout {fraction} leaves no training or no test instance")
    return world[np.sort(order[n_out:])], world[np.sort(order[:n_out])]


def _mean_std(values: list[float | None]) -> dict:
    vals = [v for v in values if v is not None]
    return {"mean": float(np.mean(vals)), "std": float(np.std(vals))} if vals else \
        {"mean": None, "std": None}


def _aggregate(reports: list[dict]) -> dict:
    """Mean ± std over seeds of one model's reports on one test set."""
    robots = list(reports[0]["per_robot_cm"])
    n_steps = len(reports[0]["per_step_cm"])
    return {
        "mean_error_cm": _mean_std([r["mean_error_cm"] for r in reports]),
        "per_seed_cm": [r["mean_error_cm"] for r in reports],
        "per_robot_cm": {b: _mean_std([r["per_robot_cm"][b] for r in reports]) for b in robots},
        "per_robot_step_cm": {b: [_mean_std([r["per_robot_step_cm"][b][i] for r in reports])
                                  for i in range(n_steps)] for b in robots},
        "first_step": reports[0]["first_step"], "step_s": reports[0]["step_s"],
    }


class LabBackdrop:
    """The lab scene rendered by its overhead camera with the robots at given ThymioLoc poses:
    Fig 2.9's camera view. The lab camera frames the 2.5 x 1.9 m arena at 3 px/cm, so its
    pixels are ThymioLoc pixels (real or collected); other scales get no backdrop."""

    def __init__(self, n_robots: int, px_per_cm: float):
        import mujoco

        from macrostate_mj.chain.scenarios import get_scenario
        from macrostate_mj.chain.world import build_world
        from macrostate_mj.vision.camera import OverheadRenderer

        self.cfg = get_scenario("lab")
        self.world = build_world(self.cfg, n_robots)
        self.data = mujoco.MjData(self.world.model)
        self.renderer = OverheadRenderer(self.world.model)
        self.px_per_cm = px_per_cm
        self.size = (self.renderer.width, self.renderer.height)
        self.colours_bgr = [tuple(int(c) for c in rgb[::-1] * 255) for rgb in self.world.colours]

    def fits(self, px: np.ndarray) -> bool:
        return (abs(self.px_per_cm - DEFAULT_PX_PER_CM) < 1e-9 and np.nanmin(px[..., :2]) >= 0
                and all(np.nanmax(px[..., i]) < self.size[i] for i in (0, 1)))

    def __call__(self, px: np.ndarray) -> np.ndarray:
        """BGR camera frame with robot i at ThymioLoc pose px[i] (x px, y px, o deg)."""
        import mujoco

        from macrostate_mj.formats.instances import from_thymioloc_pixels

        model, data = self.world.model, self.data
        for adr, (x, y, th) in zip(self.world.qpos_adr,
                                   from_thymioloc_pixels(px, self.cfg.arena, self.px_per_cm),
                                   strict=True):
            data.qpos[adr:adr + 3] = [x, y, model.qpos0[adr + 2]]
            data.qpos[adr + 3:adr + 7] = [np.cos(th / 2), 0, 0, np.sin(th / 2)]
        mujoco.mj_forward(model, data)
        return np.ascontiguousarray(self.renderer.render(data)[:, :, ::-1])

    def __enter__(self) -> LabBackdrop:
        return self

    def __exit__(self, *exc: object) -> None:
        self.renderer.close()


def run_experiment(cfg: ExperimentConfig, out: Path) -> list[str]:
    """Train, test, plot, draw; return summary lines. `out` has been checked by the caller."""
    from macrostate_mj.core.progress import LoggedProgress
    from viz.retlo_figures import plot_overall, plot_stepwise, write_video

    px = cfg.px_per_cm
    trains, tests = [], []
    for path in cfg.train:
        kept, held = _split(read_world(path, px), cfg.holdout)
        trains.append(kept)
        if len(held):
            tests.append({"name": f"holdout of {Path(path).name}", "world": held})
    tests += [{"name": Path(p).name, "world": read_world(p, px)} for p in cfg.test]
    val = read_world(cfg.val, px)
    models_dir = check_writable_dir(out / "models")
    reports = {t["name"]: {HEURISTIC: [evaluate(Heuristic2X(), t["world"])]} for t in tests}
    timings: dict[str, float] = {}
    runs = [(kind, seed) for seed in range(cfg.seeds) for kind in LEARNED]
    with LoggedProgress(transient=True) as bar:
        overall = bar.add_task("experiment retlo", total=len(runs))
        for kind, seed in runs:
            epoch_task = bar.add_task(f"{kind} seed {seed}", total=cfg.epochs)
            tcfg = TrainConfig(epochs=cfg.epochs, seed=seed, model=replace(cfg.model, kind=kind))
            start = time.perf_counter()
            net, info = fit(trains, val, tcfg, on_epoch=lambda e, v, t=epoch_task:
                            bar.update(t, completed=e + 1, description=f"val {v:.2f} cm"))
            timings[f"train_{kind}_seed{seed}"] = time.perf_counter() - start
            save_checkpoint(models_dir / f"{kind}_seed{seed}.pt", net, px, tcfg, info)
            for t in tests:
                reports[t["name"]].setdefault(kind, []).append(
                    evaluate(TorchPredictor(net), t["world"]))
            bar.remove_task(epoch_task)
            bar.advance(overall)
    results = {
        "tests": [{"name": t["name"], "n_robots": int(t["world"].shape[2]),
                   "n_instances": int(t["world"].shape[0])} for t in tests],
        "results": {name: {m: _aggregate(r) for m, r in per.items()}
                    for name, per in reports.items()},
        "seeds": cfg.seeds, "px_per_cm": px,
    }
    write_json_atomic(out / "results.json", results)
    plot_overall(results, out / "fig2_7.png")
    big = max(tests, key=lambda t: t["world"].shape[2])
    plot_stepwise(results, big["name"], out / "fig2_8.png")
    lstm0, _ = load_checkpoint(models_dir / "lstm_seed0.pt")
    shown = big["world"][:cfg.video_instances]
    est = predict_chain(TorchPredictor(lstm0), shown)
    true_px = world_to_pixels(shown, px)
    with LabBackdrop(true_px.shape[2], px) as backdrop:
        fits = backdrop.fits(true_px)
        write_video(out / "fig2_9.mp4", true_px, world_to_pixels(est, px), px,
                    backdrop=backdrop if fits else None, frame_size=backdrop.size,
                    colours=backdrop.colours_bgr if fits else None)
    write_manifest(out, "experiment retlo", cfg, None, timings,
                   products=PRODUCTS, video_test=big["name"])
    return _summary(results, timings)


def _summary(results: dict, timings: dict[str, float]) -> list[str]:
    lines = []
    for test in results["tests"]:
        res = results["results"][test["name"]]
        parts = [f"{test['name']} ({test['n_robots']} robots, {test['n_instances']} inst.):"]
        for model in (HEURISTIC, *LEARNED):
            m = res[model]["mean_error_cm"]
            parts.append(f"{model} {m['mean']:.2f} ± {m['std']:.2f} cm")
        gain = 1 - res["lstm"]["mean_error_cm"]["mean"] / res["fc"]["mean_error_cm"]["mean"]
        lines.append("  ".join(parts) + f"  (LSTM {100 * gain:.0f} % below FC)")
    for kind in LEARNED:
        secs = [v for k, v in timings.items() if k.startswith(f"train_{kind}_")]
        lines.append(f"training {kind}: {np.mean(secs):.0f} s per seed (max {max(secs):.0f} s)")
    return lines
