import json
import sys
import time
from dataclasses import replace
from pathlib import Path

from estimators.retlo.api import evaluate, fit
from estimators.retlo.files import read_world
from estimators.retlo.models import ModelConfig, TorchPredictor
from estimators.retlo.train import TrainConfig


def main():
    out = Path("/tmp/ch3/out_webots")
    train, val, test = (read_world(out / n / "instances.csv") for n in ("train", "val", "test"))
    model = ModelConfig(history=10, bidirectional=False, cos_sin=True)
    base = TrainConfig(epochs=60, seed=0, model=model)
    variants = {"ours": base, "no_feedback": replace(base, feedback=False),
                "no_chained": replace(base, chained=False),
                "no_mirror": replace(base, mirror=False),
                "no_mark": replace(base, model=replace(model, mark_estimates=False)),
                "compass_frame": replace(base, model=replace(model, rotate=False)),
                "text_like": replace(base, feedback=False, chained=False, mirror=False,
                                     model=replace(model, mark_estimates=False, rotate=False))}
    for name in sys.argv[1:] or variants:
        t0 = time.perf_counter()
        net, info = fit([train], val, variants[name])
        rep = evaluate(TorchPredictor(net), test)
        line = {"variant": name, "all_cm": round(rep["mean_error_cm"], 2),
                "per_robot_cm": {k: round(v, 2) for k, v in rep["per_robot_cm"].items()},
                "val_cm": round(info["best_val_cm"], 2), "epoch": info["best_epoch"],
                "s": round(time.perf_counter() - t0)}
        print(json.dumps(line), flush=True)
        with open("/tmp/ch3/ablate.jsonl", "a") as f:
            f.write(json.dumps(line) + "\n")


if __name__ == "__main__":
    main()
