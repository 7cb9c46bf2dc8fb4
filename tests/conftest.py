"""Shared fixtures: where the (optional) real reference data lives."""

import os
import sys
from pathlib import Path

import pytest

# Before any test module imports mujoco: headless rendering needs a GL backend chosen up front.
os.environ.setdefault("MUJOCO_GL", "egl")

# Test modules live in folders that mirror the package tree; their shared helpers (clitools) here.
sys.path.insert(0, str(Path(__file__).resolve().parent))

REPO = Path(__file__).resolve().parents[1]
def _reference() -> Path:
    """Where the package finds the ThymioLoc files (a fetched copy included)."""
    from macrostate_mj.core.paths import reference_data

    return reference_data("ReTLo")


REFERENCE = _reference()


@pytest.fixture
def reference_data() -> Path:
    """The dissertation's real data; tests that need it skip cleanly on a user's fresh clone."""
    if not REFERENCE.is_dir():
        pytest.skip(f"reference data not found at {REFERENCE} (set MACROSTATE_REFERENCE_DATA)")
    return REFERENCE


@pytest.fixture(scope="module")
def stand_in(tmp_path_factory):
    """A small lab collection standing in for the real Train.csv and Val.csv (read only): the
    sim-to-real experiments run end to end without the reference data."""
    from clitools import cli

    folder = tmp_path_factory.mktemp("s2r") / "stand_in"
    res = cli("collect", "--scenario", "lab", "--robots", "3", "--minutes", "4",
              "--episode-minutes", "2", "--seed", "77", "--split", "80/20/0",
              "--out", str(folder))
    assert res.returncode == 0, res.stderr
    return folder
