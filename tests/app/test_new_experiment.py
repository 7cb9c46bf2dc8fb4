"""Adding an experiment is one module and its test: a toy `toy-count`, written into a temporary
package that the experiments' and the sources' registries scan (`scanning`, the rule that finds
every module of `app.experiments`), is listed, runs under the run lifecycle, writes through its
record, gets its command, its generated row of test_params and of the experiments table, shows
its table through the one registry of sources, and refuses a bad flag value, with nothing else
declared. (Its name is one no user would pick: a user's own experiment may well be `hello`.)"""

from __future__ import annotations

import json
import sys
import textwrap

import pytest
from clitools import cli_inprocess
from test_params import _assert_refused, _with, experiment_args

from macrostate_mj.app.experiments import EXPERIMENTS, catalogue, names
from macrostate_mj.app.results.sources import RECORDS, SOURCES, call, reading

TOY = '''
    """`experiment toy-count`: count from the seed, a toy that holds the claim (its test:
    tests/app/test_new_experiment.py)."""

    from dataclasses import dataclass, field

    from macrostate_mj.app.experiments import register
    from macrostate_mj.app.params import Count, Seed, flag
    from macrostate_mj.app.results.sources import record, source
    from macrostate_mj.core.records import Record


    @dataclass(frozen=True)
    class Config:
        seed: int = field(default=0, metadata=flag(Seed(0, "The first number.")))
        count: int = field(default=100, metadata=flag(Count(None, "How many numbers.")))


    PROFILES = {"full": Config(), "quick": Config(count=3)}
    PRODUCTS = ["results.json"]


    @dataclass(frozen=True)
    class Results(Record):
        UNIT = "seed"

        numbers: list


    @register
    def run(config, out, progress):
        with progress.stage("count"):
            numbers = list(range(config.seed, config.seed + config.count))
            Results(numbers).write(out)
        return [f"counted {len(numbers)}"]


    @source
    def toy_count(folder):
        return [["numbers"], *([n] for n in record(Results, folder).numbers)]
'''


@pytest.fixture
def toy(tmp_path, monkeypatch):
    """The toy's package on the path and scanned, inside this test only."""
    package = tmp_path / "toy_experiments"
    package.mkdir()
    (package / "__init__.py").write_text("")
    (package / "toy_count.py").write_text(textwrap.dedent(TOY))
    monkeypatch.syspath_prepend(str(tmp_path))
    try:
        with EXPERIMENTS.scanning("toy_experiments"), SOURCES.scanning("toy_experiments"), \
                RECORDS.scanning("toy_experiments"):
            yield tmp_path
    finally:
        for module in ("toy_experiments.toy_count", "toy_experiments"):
            sys.modules.pop(module, None)
    assert "toy-count" not in names() and "toy-count" not in EXPERIMENTS
    assert "toy_count" not in SOURCES and "toy-count" not in RECORDS


def test_one_module_is_a_listed_runnable_checked_experiment(toy, capsys):
    assert "toy-count" in names()
    code, out, _ = cli_inprocess(capsys, "experiment", "list")
    assert code == 0 and any(line.split()[0] == "toy-count" for line in out.splitlines()), out

    ran = toy / "ran"
    ran.mkdir()
    row = experiment_args("toy-count", ran)
    assert row == ["--out", str(ran / "out")]        # nothing required but the output folder
    code, out, err = cli_inprocess(capsys, "experiment", "toy-count", *row, "--quick")
    assert code == 0 and "counted 3" in out, err
    assert json.loads((ran / "out" / "results.json").read_text()) == {"numbers": [0, 1, 2]}
    manifest = json.loads((ran / "out" / "manifest.json").read_text())
    assert manifest["results"]["unit"] == "seed"     # the record's, named in every run
    (ran / "index.toml").write_text('[out]\ncommand = "macrostate-mj experiment toy-count '
                                    '--quick --out results/out"\nkind = "smoke"\nunits = 1\n')
    with reading(ran):
        assert call("toy_count(out)") == [["numbers"], [0], [1], [2]]
    rows = catalogue(ran)
    assert [str(c) for c in next(r for r in rows if str(r[0]) == "toy-count")] == [
        "toy-count", "count from the seed, a toy that holds the claim (its test: "
        "tests/app/test_new_experiment.py)", "full, quick", "seed", "-", "out"]

    refused = toy / "refused"
    refused.mkdir()
    _assert_refused(_with("experiment toy-count", refused, "--count", "0"), "--count",
                    refused)
