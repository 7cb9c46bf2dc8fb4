"""Where things live: the one home of the package's folder conventions.

Robots, scenes and built-in scenarios are package data (`macrostate_mj/assets/`), found through
`importlib.resources`, so an installed wheel runs from any working directory.
"""

from __future__ import annotations

import os
from importlib.resources import files
from pathlib import Path

ASSETS = Path(str(files("macrostate_mj") / "assets" / "mjcf"))
REPO = Path(__file__).resolve().parents[2]    # the checkout, when run from one


def reference_data() -> Path:
    """The dissertation's real data: `$MACROSTATE_REFERENCE_DATA`, else `../shared/reference-data`
    beside the checkout (never part of the project)."""
    return Path(os.environ.get("MACROSTATE_REFERENCE_DATA", REPO.parent / "shared" /
                               "reference-data"))


def real_thymioloc(name: str) -> Path:
    """A published ThymioLoc 3-robot file (Train.csv, Val.csv)."""
    return reference_data() / "ReTLo" / "Datasets" / "3Robots" / name
