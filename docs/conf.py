"""Sphinx configuration: the MuJoCo documentation's stack (Sphinx, furo, MyST)."""

import os
import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
sys.path[:0] = [str(DOCS / "_ext"), str(DOCS.parent)]
os.environ.setdefault("MUJOCO_GL", "egl")

project = "macrostate-mj"
author = "the macrostate-mj developers"
copyright = "2026, " + author
from importlib.metadata import version as _version  # noqa: E402

release = _version("macrostate-mj")

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "results",
    "cli_reference",
]
myst_enable_extensions = ["colon_fence", "deflist"]
myst_heading_anchors = 3
source_suffix = {".md": "markdown"}
exclude_patterns = ["_build"]
html_theme = "furo"
smartquotes = False        # "--flag" must stay two hyphens, not an en dash
html_title = "macrostate-mj"
html_static_path = ["_static"]
html_css_files = ["results.css"]
autodoc_typehints = "description"
autodoc_member_order = "bysource"
autodoc_default_options = {"members": True, "undoc-members": False}
nitpicky = False
# Every page is in a toctree; a broken internal link or cross-reference is a warning, and
# `make docs` turns warnings into errors.
suppress_warnings: list[str] = []
