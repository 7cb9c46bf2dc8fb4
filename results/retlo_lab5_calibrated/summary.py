"""summary.json from reports/: per arm (trained: the regions fitted on the lab 3-robot
validation file during training; refitted: `calibrate retlo` on the 5-robot lab chains of seed
3), the mean error and the calibration per robot and pooled on the 5-robot test chains, mean ±
std over the model seeds (`mean_std`, as every results file gives it)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from macrostate_mj.core.stats import mean_std

KEYS = ("coverage_50", "coverage_90", "gaussian_coverage_50", "gaussian_coverage_90", "nll")


def main(reports: str) -> None:
    folder = Path(reports)
    out = {}
    for arm in ("trained", "refitted"):
        runs = [json.loads(p.read_text()) for p in sorted(folder.glob(f"{arm}_s*.json"))]
        if not runs:
            continue
        who = [k for k in runs[0]["calibration"] if k != "nll_unit"]
        out[arm] = {"seeds": len(runs),
                    "mean_error_cm": mean_std([r["mean_error_cm"] for r in runs]),
                    "calibration": {w: {k: mean_std([r["calibration"][w][k] for r in runs])
                                        for k in KEYS if k in runs[0]["calibration"][w]}
                                    for w in who}}
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main(sys.argv[1])
