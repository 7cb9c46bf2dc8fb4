"""macrostate-mj: a MuJoCo testbed for macrostate estimation (robot chains, ant colonies)."""

import os

# MuJoCo picks its GL backend when first imported; headless machines need one chosen up front.
os.environ.setdefault("MUJOCO_GL", "egl")

__version__ = "0.1.0"
