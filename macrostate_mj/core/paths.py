"""Where things live: the one home of the repository's folder conventions."""

from __future__ import annotations

import os
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
ASSETS = REPO / "assets" / "mjcf"


def reference_data() -> Path:
    """The dissertation's real data: `$MACROSTATE_REFERENCE_DATA`, else `../shared/reference-data`
    beside the checkout (never part of the project)."""
    return Path(os.environ.get("MACROSTATE_REFERENCE_DATA", REPO.parent / "shared" /
                               "reference-data"))


def real_thymioloc(name: str) -> Path:
    """A published ThymioLoc 3-robot file (Train.csv, Val.csv)."""
    return reference_data() / "ReTLo" / "Datasets" / "3Robots" / name
