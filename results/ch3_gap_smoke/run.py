import json
import sys
import time
from pathlib import Path

import macrostate_mj.app.experiments.srs as srs
from estimators.retlo.files import read_world
from macrostate_mj.chain.scenarios import get_scenario


def main():
    variant, out = sys.argv[1], Path(sys.argv[2])
    config = srs.Config(train=100, val=50, test=50, scenario=get_scenario(variant))
    t0 = time.perf_counter()
    sets = [srs._Dataset(out / "train", 3, 100, 0), srs._Dataset(out / "val", 3, 50, 500),
            srs._Dataset(out / "test", 5, 50, 900)]
    for ds in sets:
        ds.ensure(config, 2, None)
    t1 = time.perf_counter()
    task = srs.ModelTask(read_world(sets[0].csv), sets[1].csv, sets[2].csv, epochs=60, seed=0)
    rep = json.loads(task.compute()["report.json"])
    line = {"variant": variant, "all_cm": rep["mean_error_cm"], "per_robot_cm": rep["per_robot_cm"],
            "best_val_cm": rep["best_val_cm"], "collect_s": round(t1 - t0),
            "train_s": round(time.perf_counter() - t1)}
    print(json.dumps(line), flush=True)
    with open("/tmp/ch3/results.jsonl", "a") as f:
        f.write(json.dumps(line) + "\n")


if __name__ == "__main__":
    main()
