"""Adding an experiment is one module and its test: a toy `hello`, written into a temporary
package that the experiments' registry scans (`EXPERIMENTS.scanning`, the rule that finds every
module of `app.experiments`), is listed, runs under the run lifecycle, gets its command and its
generated row of test_params, and refuses a bad flag value, with nothing else declared."""

from __future__ import annotations

import json
import sys
import textwrap

import pytest
from clitools import cli_inprocess
from test_params import _assert_refused, _with, experiment_args

from macrostate_mj.app.experiments import EXPERIMENTS, names

HELLO = '''
    """`experiment hello`: count from the seed, a toy that holds the claim (its test:
    tests/app/test_new_experiment.py)."""

    import json
    from dataclasses import dataclass, field

    from macrostate_mj.app.experiments import register
    from macrostate_mj.app.params import Count, Seed, flag


    @dataclass(frozen=True)
    class Config:
        seed: int = field(default=0, metadata=flag(Seed(0, "The first number.")))
        count: int = field(default=100, metadata=flag(Count(None, "How many numbers.")))


    PROFILES = {"full": Config(), "quick": Config(count=3)}
    PRODUCTS = ["results.json"]


    @register
    def run(config, out, progress):
        with progress.stage("count"):
            numbers = list(range(config.seed, config.seed + config.count))
            (out / "results.json").write_text(json.dumps({"numbers": numbers}))
        return [f"counted {len(numbers)}"]
'''


@pytest.fixture
def hello(tmp_path, monkeypatch):
    """The toy's package on the path and scanned, inside this test only."""
    package = tmp_path / "toy_experiments"
    package.mkdir()
    (package / "__init__.py").write_text("")
    (package / "hello.py").write_text(textwrap.dedent(HELLO))
    monkeypatch.syspath_prepend(str(tmp_path))
    try:
        with EXPERIMENTS.scanning("toy_experiments"):
            yield tmp_path
    finally:
        for module in ("toy_experiments.hello", "toy_experiments"):
            sys.modules.pop(module, None)
    assert "hello" not in names() and "hello" not in EXPERIMENTS


def test_one_module_is_a_listed_runnable_checked_experiment(hello, capsys):
    assert "hello" in names()
    code, out, _ = cli_inprocess(capsys, "experiment", "list")
    assert code == 0 and any(line.split()[0] == "hello" for line in out.splitlines()), out

    ran = hello / "ran"
    ran.mkdir()
    row = experiment_args("hello", ran)
    assert row == ["--out", str(ran / "out")]        # nothing required but the output folder
    code, out, err = cli_inprocess(capsys, "experiment", "hello", *row, "--quick")
    assert code == 0 and "counted 3" in out, err
    assert json.loads((ran / "out" / "results.json").read_text()) == {"numbers": [0, 1, 2]}
    assert json.loads((ran / "out" / "manifest.json").read_text())

    refused = hello / "refused"
    refused.mkdir()
    _assert_refused(_with("experiment hello", refused, "--count", "0"), "--count", refused)
