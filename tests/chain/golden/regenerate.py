"""Regenerate the golden trajectory on purpose (after an intended physics change):

    .venv/bin/python tests/chain/golden/regenerate.py
"""

import sys
from pathlib import Path

import numpy as np

sys.path[:0] = [str(Path(__file__).resolve().parents[i]) for i in (1, 2)]
from test_physics import GOLDEN, golden_run  # noqa: E402

if __name__ == "__main__":
    np.savez_compressed(GOLDEN, poses=golden_run())
    print(f"wrote {GOLDEN}")
