"""The README's Python API example runs as written and does what its comments say."""

import re

import numpy as np
from conftest import REPO


def _blocks() -> list[str]:
    text = (REPO / "README.md").read_text()
    section = text.split("## Python API", 1)[1].split("\n## ", 1)[0]
    return re.findall(r"```python\n(.*?)```", section, re.S)


def test_the_readme_python_api_example_runs():
    scope: dict = {}
    exec(compile(_blocks()[0], "README.md:Python API", "exec"), scope)
    sim, seen, frame = scope["sim"], scope["seen"], scope["frame"]
    assert abs(sim.time - 10.0) < 1e-9 and sim.poses.shape == (5, 3)
    assert frame.shape == (570, 750, 3) and frame.dtype == np.uint8
    assert seen.detected.all()
    assert np.abs(seen.poses[:, :2] - sim.poses[:, :2]).max() < 0.005


def test_the_readme_environment_example_runs():
    scope: dict = {}
    exec(compile(_blocks()[1], "README.md:Python API (environment)", "exec"), scope)
    assert scope["obs"]["tail"].shape == (10, 3) and scope["frame"].shape == (570, 750, 3)
