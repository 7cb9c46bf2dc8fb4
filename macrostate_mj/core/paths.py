"""Where things live: the one home of the package's folder conventions.

Robots, scenes and built-in scenarios are package data (`macrostate_mj/assets/`), found through
`importlib.resources`, so an installed wheel runs from any working directory.
"""

from __future__ import annotations

import os
from importlib.resources import files
from pathlib import Path

ASSETS = Path(str(files("macrostate_mj") / "assets" / "mjcf"))
MODELS = ASSETS.parent / "models"       # trained estimators the package ships (README.md there)


def _checkout() -> Path | None:
    """The source checkout this package runs from, or None when it is installed (a wheel in
    site-packages has no pyproject.toml beside it), so checkout conventions never leak into
    site-packages' parent folders."""
    root = Path(__file__).resolve().parents[2]
    return root if (root / "pyproject.toml").is_file() else None


CHECKOUT = _checkout()


def reference_data() -> Path:
    """The dissertation's real data (never part of the project): `$MACROSTATE_REFERENCE_DATA`;
    else the copy `macrostate-mj data fetch` made (`core.datasets.cache_root`) once it holds
    one; else, run from a checkout, `../shared/reference-data` beside it where that exists;
    else the fetch cache. A missing dataset is reported where it is read, naming the fetch."""
    from macrostate_mj.core.datasets import DATASETS, cache_root

    if env := os.environ.get("MACROSTATE_REFERENCE_DATA"):
        return Path(env)
    cache = cache_root()
    if any((cache / d.folder).is_dir() for d in DATASETS.values()):
        return cache
    if CHECKOUT is not None and (CHECKOUT.parent / "shared" / "reference-data").is_dir():
        return CHECKOUT.parent / "shared" / "reference-data"
    return cache


def real_thymioloc(name: str) -> Path:
    """A published ThymioLoc 3-robot file (Train.csv, Val.csv)."""
    return reference_data() / "ReTLo" / "Datasets" / "3Robots" / name
