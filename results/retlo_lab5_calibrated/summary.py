"""summary.json from reports/: per arm (trained: the regions fitted on the lab 3-robot
validation file during training; refitted: `calibrate retlo` on the 5-robot lab chains of seed
3), the mean error and the calibration per robot and pooled on the 5-robot test chains, mean ±
std over the model seeds."""

from __future__ import annotations

import json
import statistics
import sys
from pathlib import Path

KEYS = ("coverage_50", "coverage_90", "gaussian_coverage_50", "gaussian_coverage_90", "nll")


def _ms(values: list[float]) -> dict:
    return {"mean": statistics.fmean(values), "std": statistics.stdev(values) if len(values) > 1
            else 0.0, "n": len(values)}


def main(reports: str) -> None:
    folder = Path(reports)
    out = {}
    for arm in ("trained", "refitted"):
        runs = [json.loads(p.read_text()) for p in sorted(folder.glob(f"{arm}_s*.json"))]
        if not runs:
            continue
        who = [k for k in runs[0]["calibration"] if k != "nll_unit"]
        out[arm] = {"seeds": len(runs),
                    "mean_error_cm": _ms([r["mean_error_cm"] for r in runs]),
                    "calibration": {w: {k: _ms([r["calibration"][w][k] for r in runs])
                                        for k in KEYS if k in runs[0]["calibration"][w]}
                                    for w in who}}
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main(sys.argv[1])
