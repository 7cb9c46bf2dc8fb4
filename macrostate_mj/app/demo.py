"""`make demo`: the main jobs on the embedded default scenario, then where their outputs are.

1. a 5-robot `lab` chain for 60 s with an overhead video and a rerun recording;
2. small tracked 3-robot and 5-robot `lab` datasets, and their statistics beside the real data's;
3. an LSTM trained on the 3-robot data only, evaluated on the 5-robot data (modular inference).

Each stage is the CLI command a user would type, run in this process.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from macrostate_mj.core.paths import real_thymioloc

REAL_TRAIN = real_thymioloc("Train.csv")


def run(*args: str) -> None:
    """One CLI command in-process; a failure stops the demo with the command's own message."""
    from macrostate_mj.app.cli import main

    print(f"\n$ macrostate-mj {' '.join(args)}", flush=True)
    try:
        main(list(args))
    except SystemExit as done:
        if done.code not in (0, None):
            raise


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", type=Path, default=Path("out/demo"))
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args(argv)
    out: Path = args.out
    w = str(args.workers)
    try:
        print("demo 1/3: a 5-robot lab chain, 60 simulated seconds, video and rerun recording")
        run("simulate", "--scenario", "lab", "--robots", "5", "--seconds", "60", "--seed", "0",
            "--out", str(out / "lab5"), "--video", str(out / "lab5.mp4"),
            "--rerun", str(out / "lab5.rrd"), "--overwrite")

        print("\ndemo 2/3: tracked 3-robot and 5-robot lab datasets (ThymioLoc layout)")
        run("collect", "--robots", "3", "--minutes", "10", "--seed", "1", "--workers", w,
            "--split", "60/10/30", "--out", str(out / "lab3_data"), "--overwrite")
        run("collect", "--robots", "5", "--minutes", "5", "--seed", "2", "--workers", w,
            "--out", str(out / "lab5_data"), "--overwrite")
        files = [str(out / "lab3_data" / "instances.csv"), str(out / "lab5_data" / "instances.csv")]
        run("stats", *files, *([str(REAL_TRAIN)] if REAL_TRAIN.exists() else []))

        print("\ndemo 3/3: an LSTM trained on 3-robot data, evaluated on 5-robot teams")
        run("train", "retlo", "--model", "lstm", "--train", str(out / "lab3_data" / "Train.csv"),
            "--val", str(out / "lab3_data" / "Val.csv"), "--out", str(out / "lstm.pt"),
            "--seed", "0", "--epochs", "40", "--overwrite")
        run("evaluate", "retlo", "--model", str(out / "lstm.pt"),
            "--data", str(out / "lab5_data" / "instances.csv"),
            "--out", str(out / "lstm_on_lab5.json"), "--overwrite")
    except SystemExit as failed:
        return int(failed.code or 1)
    print(f"\nall outputs are under {out.resolve()}:")
    print(f"  video {out / 'lab5.mp4'}, rerun {out / 'lab5.rrd'} (view: rerun {out / 'lab5.rrd'})")
    print(f"  datasets {out / 'lab3_data'}, {out / 'lab5_data'}; model {out / 'lstm.pt'}")
    print(f"  5-robot evaluation {out / 'lstm_on_lab5.json'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
