"""macrostate-mj: a MuJoCo testbed for macrostate estimation (robot chains, ant colonies)."""

import os

# MuJoCo picks its GL backend when first imported; headless machines need one chosen up front.
os.environ.setdefault("MUJOCO_GL", "egl")

__version__ = "0.1.0"

# The Tail environments' Gymnasium ids, by entry point only (`gym_ids`): plain `import
# macrostate_mj`, and so gymnasium's "macrostate_mj:<id>" form, is enough to make them.
from macrostate_mj import gym_ids as _gym_ids  # noqa: E402

_gym_ids.register()
