"""The held-out fold: the real 3-robot Train.csv split as `experiment retlo --holdout 0.25`
splits it (25 % of the instances, chosen by a generator of seed 0), written as raw ThymioLoc
rows into data/ (git-ignored: splits of real data are not kept)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from macrostate_mj.formats.thymioloc import read_csv, write_csv


def main(train_csv: str, out: str) -> None:
    poses = read_csv(train_csv).poses
    order = np.random.default_rng(0).permutation(len(poses))
    n_out = int(round(0.25 * len(poses)))
    Path(out).mkdir(parents=True, exist_ok=True)
    write_csv(Path(out) / "kept.csv", poses[np.sort(order[n_out:])])
    write_csv(Path(out) / "held.csv", poses[np.sort(order[:n_out])])


if __name__ == "__main__":
    main(*sys.argv[1:3])
