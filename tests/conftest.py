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
