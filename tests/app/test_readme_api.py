"""The README's Python API example runs as written and does what its comments say."""

import re

import numpy as np
from conftest import REPO


def test_the_readme_python_api_example_runs():
    text = (REPO / "README.md").read_text()
    section = text.split("## Python API", 1)[1].split("\n## ", 1)[0]
    code = re.search(r"```python\n(.*?)```", section, re.S).group(1)
    scope: dict = {}
    exec(compile(code, "README.md:Python API", "exec"), scope)
    sim, seen, frame = scope["sim"], scope["seen"], scope["frame"]
    assert abs(sim.time - 10.0) < 1e-9 and sim.poses.shape == (5, 3)
    assert frame.shape == (570, 750, 3) and frame.dtype == np.uint8
    assert seen.detected.all()
    assert np.abs(seen.poses[:, :2] - sim.poses[:, :2]).max() < 0.005
