"""Copy each model's task report of an `experiment srs --profile PROFILE` run (default
fig3.5b) out of its task cache, named as `results/srs_full/models/` names its float32 twins
(`<configuration>_b<budget %>_d<dataset>_m<model seed>.json`), so the two pair up.

    python reports.py OUT PRECISION DEST [PROFILE]   # /tmp/srs_bf16 bf16 results/srs_fig35b_bf16

The tasks are rebuilt exactly as `experiment srs` builds them (same data, same keys).
"""

import shutil
import sys
from pathlib import Path

from estimators.retlo.files import read_world
from macrostate_mj.app.experiments.srs import PROFILES, ModelTask, _budgets, _Dataset, _datasets

out, precision, dest = Path(sys.argv[1]), sys.argv[2], Path(sys.argv[3])
config = PROFILES[sys.argv[4] if len(sys.argv) > 4 else "fig3.5b"]
data = out / "data"
val = _Dataset(data / "val", 3, config.val, config.seed * 1000 + 500, "passive")
test = _Dataset(data / "test", config.test_robots, config.test, config.seed * 1000 + 900,
                "passive")
here = dest / "models"
here.mkdir(parents=True, exist_ok=True)
for name, sets in _datasets(config, data).items():
    worlds = [read_world(ds.csv) for ds in sets]
    for budget in _budgets(config, name):
        for d, world in enumerate(worlds):
            for m in range(config.models):
                task = ModelTask(world[:int(round(budget * config.train))], val.csv, test.csv,
                                 config.epochs, m, precision)
                shutil.copyfile(out / "cache" / task.stage / task.key() / "report.json",
                                here / f"{name}_b{round(budget * 100)}_d{d}_m{m}.json")
