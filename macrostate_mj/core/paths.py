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


def reference_data(folder: str | None = None) -> Path:
    """The root of the dissertation's real data (never part of the project), for the dataset
    in `folder` under it (`ReTLo`, `OpticalFlows_HsAnts`): `$MACROSTATE_REFERENCE_DATA`; else
    the copy `macrostate-mj data fetch` verified (`core.datasets.cache_root`); else, run from a
    checkout, `../shared/reference-data` beside it where it holds that folder; else the fetch
    cache. A missing dataset is reported where it is read, naming the fetch. Without `folder`,
    the fetch cache once it holds any verified dataset."""
    from macrostate_mj.core.datasets import DATASETS, cache_root, fetched

    if env := os.environ.get("MACROSTATE_REFERENCE_DATA"):
        return Path(env)
    cache = cache_root()
    names = [folder] if folder else [d.folder for d in DATASETS.values()]
    if any(fetched(cache, n) for n in names):
        return cache
    shared = None if CHECKOUT is None else CHECKOUT.parent / "shared" / "reference-data"
    if shared is not None and (shared / (folder or "")).is_dir():
        return shared
    return cache


def real_dataset(folder: str) -> Path:
    """A real dataset's folder (`ReTLo`, `OpticalFlows_HsAnts`) where `reference_data` finds
    it."""
    return reference_data(folder) / folder


def real_thymioloc(name: str = "") -> Path:
    """A published ThymioLoc 3-robot file (Train.csv, Val.csv), or their folder."""
    return real_dataset("ReTLo") / "Datasets" / "3Robots" / name
