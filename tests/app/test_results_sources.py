"""The results sources that pages and claims share (`app.results.sources`): paired differences
over a folder's independent units, read through the experiments' typed records."""

import json

import pytest

from macrostate_mj.app.experiments.sim2real import Results as Sim2RealResults
from macrostate_mj.app.results.sources import SOURCES, call, paired, reading
from macrostate_mj.core.evidence import Design, Figure
from macrostate_mj.core.records import RecordError


def _index(root) -> None:
    (root / "index.toml").write_text('[a]\ncommand = "x"\nkind = "result"\nunits = 5\n')


def _run(root, folder: str, first: int, x: dict, y: dict, folds: int = 5) -> None:
    """A sim-to-real run's record with two per-seed maps (`arms/x`, `arms/y`)."""
    (root / folder).mkdir()
    Sim2RealResults({"folds": folds, "seed": first, "seeds": len(x)}, 0,
                    {"x": x, "y": y}).write(root / folder)
    (root / folder / "manifest.json").write_text(json.dumps({"command": "experiment sim2real"}))


def test_a_paired_difference_pools_the_seeds_of_several_runs(tmp_path):
    """`paired(a.json+b.json, ...)`: runs of other seeds on the same folds pool their seeds; a
    seed named by two runs is refused rather than silently overwritten."""
    _index(tmp_path)
    (tmp_path / "a.json").write_text(json.dumps({"x": {"0": 2.0, "1": 4.0},
                                                 "y": {"0": 1.0, "1": 1.0}}))
    (tmp_path / "b.json").write_text(json.dumps({"x": {"5": 4.0}, "y": {"5": 1.0}}))
    with reading(tmp_path):
        pooled = paired("a.json+b.json", "x", "y")
        assert pooled.n == 3 and pooled.mean == pytest.approx(7 / 3)     # 1, 3 and 3
        assert paired("a.json", "x", "y").n == 2
        assert ", 3 seeds: " in str(pooled)     # no record with folds: each seed is a unit
        with pytest.raises(ValueError, match="more than one run"):
            paired("a.json+a.json", "x", "y")


def test_a_paired_difference_is_over_folds_not_seeds(tmp_path):
    """Sim-to-real runs: seeds s and s + 5 share fold s, so ten seeds are five units, averaged
    to the fold before the interval, and the folds share training data, so the interval is the
    Nadeau-Bengio corrected one the claims draw (`Design`), its units named beside it: what the
    run's record (`sim2real.Results.design_of`) says, not a guess."""
    from macrostate_mj.core import stats

    _index(tmp_path)
    d1 = {"0": 1.0, "1": 0.2, "2": 0.9, "3": 0.1, "4": 0.6}
    d2 = {"5": 0.5, "6": 0.7, "7": 0.8, "8": 0.4, "9": 0.3}
    _run(tmp_path, "a", 0, d1, dict.fromkeys(d1, 0.0))
    _run(tmp_path, "b", 5, d2, dict.fromkeys(d2, 0.0))
    with reading(tmp_path):
        one = paired("a/results.json", "arms/x", "arms/y")
        ms = stats.mean_std(list(d1.values()))
        ci = stats.t_interval(ms["mean"], ms["std"], 5, ratio=stats.cv_ratio(5))
        assert (one.n, one.low, one.high) == (5, pytest.approx(ci[0]), pytest.approx(ci[1]))
        assert ", 5 folds, Nadeau-Bengio corrected: " in str(one)
        pooled = paired("a/results.json+b/results.json", "arms/x", "arms/y")
        folds = {str(f): (d1[str(f)] + d2[str(f + 5)]) / 2 for f in range(5)}
        want = Design("fold", folds=5).apply(Figure.of(folds))
        assert pooled.n == 5 and pooled.mean == pytest.approx(want.mean)
        assert (pooled.low, pooled.high) == pytest.approx(want.interval())
        assert ", 5 folds, seeds averaged within each, Nadeau-Bengio corrected: " in str(pooled)
        _run(tmp_path, "c", 5, d2, dict.fromkeys(d2, 0.0), folds=4)
        with pytest.raises(ValueError, match="different folds"):
            paired("a/results.json+c/results.json", "arms/x", "arms/y")


def test_a_renamed_key_fails_where_the_record_is_read(tmp_path):
    """A results file whose keys are not its record's is refused by name, in one line."""
    _index(tmp_path)
    _run(tmp_path, "a", 0, {"0": 1.0}, {"0": 0.0})
    data = json.loads((tmp_path / "a" / "results.json").read_text())
    data["arm_table"] = data.pop("arms")
    (tmp_path / "a" / "results.json").write_text(json.dumps(data))
    with reading(tmp_path), pytest.raises(RecordError, match=r"unknown keys \['arm_table'\]"):
        call("s2r(a)")


def test_every_source_has_one_name_and_is_found_by_the_scan():
    """Pages and claims call one registry: the generic sources and each experiment's."""
    assert {"json", "meanstd", "paired", "runs", "srs", "srs_table", "s2r", "sealed",
            "oc_auc", "retlo_error", "soak_table", "bench", "sysid_ks"} <= set(SOURCES)
