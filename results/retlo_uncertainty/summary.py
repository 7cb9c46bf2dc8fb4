"""summary.json from reports/: per evaluation set (held: the held-out 25 % of Train; val: Val,
which selected the checkpoints), the point and Gaussian LSTMs' mean error per seed, their ratio,
and the Gaussian models' (and the ensemble's) pooled calibration."""

from __future__ import annotations

import json
import sys
from pathlib import Path


def main(reports: str) -> None:
    folder = Path(reports)
    out = {}
    for part in ("held", "val"):
        def read(name: str, part: str = part) -> dict | None:
            path = folder / f"{name}_{part}.json"
            return json.loads(path.read_text()) if path.is_file() else None

        seeds = [s for s in range(5) if read(f"point_s{s}") and read(f"gauss_s{s}")]
        point = [read(f"point_s{s}")["mean_error_cm"] for s in seeds]
        gauss = [read(f"gauss_s{s}") for s in seeds]
        row = {"seeds": seeds, "point_cm": point,
               "gaussian_cm": [g["mean_error_cm"] for g in gauss],
               "gaussian_calibration": [g["calibration"]["pooled"] for g in gauss]}
        if seeds:
            row["mean_point_cm"] = sum(point) / len(point)
            row["mean_gaussian_cm"] = sum(row["gaussian_cm"]) / len(seeds)
            row["gaussian_vs_point"] = row["mean_gaussian_cm"] / row["mean_point_cm"] - 1
        ens = read("ensemble")
        if ens is not None:
            row["ensemble_cm"] = ens["mean_error_cm"]
            row["ensemble_calibration"] = ens["calibration"]["pooled"]
        out[part] = row
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main(sys.argv[1])
