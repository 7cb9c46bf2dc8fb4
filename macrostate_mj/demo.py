"""`make demo`: the main job on the embedded default scenario, then where its outputs are."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from macrostate_mj.errors import UserError


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", type=Path, default=Path("out/demo"))
    args = parser.parse_args(argv)
    from macrostate_mj.cli.progress import sim_progress
    from macrostate_mj.runs import SimulateRequest, simulate_run

    out: Path = args.out
    req = SimulateRequest("lab", 5, 60.0, 0, out / "lab5", video=out / "lab5.mp4",
                          rerun=out / "lab5.rrd", overwrite=True)
    print("demo 1/1: 5-robot lab chain, 60 simulated seconds, video and rerun recording")
    try:
        with sim_progress(req.seconds, "simulating") as advance:
            written = simulate_run(req, advance)
    except UserError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    print("outputs:")
    for kind, path in written.items():
        print(f"  {kind:<9} {path.resolve()}")
    print("view the recording with: rerun " + str(written["rerun"]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
