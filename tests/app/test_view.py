"""`view`: MuJoCo's viewer with the controllers running, or one line without a display."""

import os
import shutil
import subprocess
import sys

import pytest
from clitools import assert_clean_error, cli


def test_without_a_display_view_says_so_in_one_line():
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    assert_clean_error(cli("view", "--robots", "3", "--seconds", "1", env=env), "no display",
                       "simulate --video")


@pytest.mark.skipif(shutil.which("xvfb-run") is None, reason="Xvfb not installed (Debian: xvfb)")
def test_view_runs_the_chain_under_xvfb():
    res = subprocess.run(["xvfb-run", "-a", sys.executable, "-m", "macrostate_mj.app.cli",
                          "view", "--robots", "3", "--seconds", "2", "--speed", "4"],
                         capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    assert "viewed 2.0 simulated s of lab with 3 robots" in res.stdout
