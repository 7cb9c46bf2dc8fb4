"""`experiment sim2real`: cross-validated folds that never leak, the data-saving arithmetic, bad
input, and a quick end-to-end run (a small lab collection stands in for the real files, so the
test needs no reference data)."""

import json
import shutil
from dataclasses import replace

import numpy as np
import pytest
from clitools import assert_clean_error, cli

from macrostate_mj.app.experiments import cv_blocks, execute, sim2real
from macrostate_mj.app.experiments.sim2real import PROFILES, equivalent_fraction
from macrostate_mj.chain import scenarios
from macrostate_mj.core.errors import UserError


@pytest.mark.parametrize("fold", range(5))
def test_folds_are_contiguous_and_disjoint(fold):
    pool, val, test = cv_blocks(325, 5, fold, 0.15)
    assert np.array_equal(test, np.arange(test[0], test[-1] + 1))
    assert not set(test) & set(pool) and not set(test) & set(val) and not set(pool) & set(val)
    assert len(pool) + len(val) + len(test) == 325 and len(test) == 65
    assert val.min() > pool.max() or fold == 4 and val.min() > pool.max()
    with pytest.raises(UserError):
        cv_blocks(3, 5, 0, 0.15)


def test_equivalent_fraction_interpolates_in_log_share():
    fractions, errors = (0.1, 0.25, 0.5, 1.0), [8.0, 6.0, 5.0, 4.0]
    assert equivalent_fraction(6.0, fractions, errors) == pytest.approx(0.25)
    assert equivalent_fraction(4.5, fractions, errors) == pytest.approx(np.sqrt(0.5))
    assert equivalent_fraction(3.0, fractions, errors) is None       # better than all real data
    assert equivalent_fraction(9.0, fractions, errors) is None       # worse than the least
    assert equivalent_fraction(5.5, fractions, [8.0, 5.0, 6.0, 4.0]) == pytest.approx(
        np.exp(np.log(0.1) + 5 / 6 * (np.log(0.25) - np.log(0.1))))  # a noisy bump is ignored


def test_experiment_sim2real_quick(tmp_path, monkeypatch):
    stand_in = tmp_path / "stand_in"
    res = cli("collect", "--scenario", "lab", "--robots", "3", "--minutes", "4",
              "--episode-minutes", "2", "--seed", "77", "--split", "80/20/0",
              "--out", str(stand_in))
    assert res.returncode == 0, res.stderr
    out = tmp_path / "s2r"
    res = cli("experiment", "sim2real", "--quick", "--real", str(stand_in), "--out", str(out))
    assert res.returncode == 0, res.stderr
    results = json.loads((out / "results.json").read_text())
    assert set(results["arms"]) == {"sim", "real", "finetune", "mixed"}
    for arm in ("real", "finetune", "mixed"):
        assert set(results["arms"][arm]) == {"0.5", "1"}
        assert all(c["head_cm"]["n"] == 2 and c["head_cm"]["mean"] > 0
                   for c in results["arms"][arm].values())
    assert results["sim_over_real"] > 0
    assert (out / "sim2real.png").stat().st_size > 1000
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["models"] == manifest["models_trained"] == 2 + 3 * 2 * 2
    models = sorted((out / "cache" / "sim2real-model").iterdir())
    assert len(models) == 14 and sum((m / "model.pt").is_file() for m in models) == 2
    # a rerun takes every model from the cache and writes the same results
    before = (out / "results.json").read_bytes()
    res = cli("experiment", "sim2real", "--quick", "--real", str(stand_in), "--out", str(out),
              "--overwrite")
    assert res.returncode == 0, res.stderr
    assert (out / "results.json").read_bytes() == before
    assert json.loads((out / "manifest.json").read_text())["models_trained"] == 0
    # killed while training: the manifest says so, one real-data model is missing; the same
    # command resumes (no --overwrite) and trains that model alone
    manifest = json.loads((out / "manifest.json").read_text())
    (out / "manifest.json").write_text(json.dumps({**manifest, "status": "interrupted"}))
    shutil.rmtree(next(m for m in models if not (m / "model.pt").exists()))
    res = cli("experiment", "sim2real", "--quick", "--real", str(stand_in), "--out", str(out))
    assert res.returncode == 0, res.stderr
    assert (out / "results.json").read_bytes() == before
    assert json.loads((out / "manifest.json").read_text())["models_trained"] == 1
    # new inputs make new data, never reuse the old: a refit lab (or a randomized one) is
    # collected again, and its CSVs' bytes key the sim models
    collected = []

    class Stop(Exception):
        pass

    def collect(req):
        collected.append(req)
        raise Stop

    monkeypatch.setattr(sim2real, "collect", collect)
    config = replace(PROFILES["quick"], real=stand_in)
    with pytest.raises(Stop):
        execute("sim2real", replace(config, randomize="wide"), out, overwrite=True)
    refit = scenarios.SCENARIOS["lab"].with_overrides(marker_jitter=0.004)
    monkeypatch.setitem(scenarios.SCENARIOS, "lab", refit)
    with pytest.raises(Stop):
        execute("sim2real", config, out, overwrite=True)
    other = tmp_path / "other_lab.toml"        # another lab's file: collected in that lab
    other.write_text('extends = "lab"\nname = "other_lab"\n[chain]\nspacing = 0.25\n')
    with pytest.raises(Stop):
        execute("sim2real", replace(config, scenario=other), out, overwrite=True)
    assert [r.randomize for r in collected] == ["wide", None, None]
    assert collected[-1].scenario == other
    assert (out / "results.json").read_bytes() == before


def test_arms_train_only_what_they_need(tmp_path):
    """`--arm sim` trains the sim models alone (no ratio without the real arm); `--arm real`
    collects no lab data; an unknown arm is one line, exit 2."""
    stand_in = tmp_path / "stand_in"
    res = cli("collect", "--scenario", "lab", "--robots", "3", "--minutes", "3",
              "--episode-minutes", "1.5", "--seed", "78", "--split", "80/20/0",
              "--out", str(stand_in))
    assert res.returncode == 0, res.stderr
    for arms, trained in ((["sim"], 2), (["real"], 4), (["real", "sim"], 2)):
        out = tmp_path / "_".join(arms)
        args = [a for arm in arms for a in ("--arm", arm)]
        res = cli("experiment", "sim2real", "--quick", "--real", str(stand_in), *args,
                  "--out", str(out))
        assert res.returncode == 0, res.stderr
        results = json.loads((out / "results.json").read_text())
        assert set(results["arms"]) == set(arms)
        assert ("sim_over_real" in results) == (len(arms) == 2)
        assert (out / "data" / "sim").exists() == ("sim" in arms)
        manifest = json.loads((out / "manifest.json").read_text())
        assert manifest["models_trained"] == (trained if len(arms) == 1 else 6)
    res = cli("experiment", "sim2real", "--quick", "--real", str(stand_in), "--arm", "tail",
              "--out", str(tmp_path / "bad"))
    assert_clean_error(res, "--arm")
    assert not (tmp_path / "bad").exists()


def test_sim2real_refuses_a_folder_without_real_files(tmp_path):
    empty = tmp_path / "empty"
    empty.mkdir()
    res = cli("experiment", "sim2real", "--quick", "--real", str(empty), "--out",
              str(tmp_path / "out"))
    assert res.returncode == 2
    assert res.stderr.count("\n") == 1 and "Train.csv" in res.stderr
    assert not (tmp_path / "out").exists()


def test_sim_minutes_with_a_given_sim_folder_is_refused(tmp_path):
    res = cli("experiment", "sim2real", "--quick", "--real", str(tmp_path), "--sim",
              str(tmp_path), "--sim-minutes", "5", "--out", str(tmp_path / "out"))
    assert_clean_error(res, "--sim-minutes")
    assert not (tmp_path / "out").exists()
    res = cli("experiment", "sim2real", "--quick", "--real", str(tmp_path), "--sim",
              str(tmp_path), "--scenario", "webots", "--out", str(tmp_path / "out"))
    assert_clean_error(res, "--scenario")
    assert not (tmp_path / "out").exists()
    for bad in ("1.5", "0"):
        res = cli("experiment", "sim2real", "--quick", "--real", str(tmp_path), "--fraction", bad,
                  "--out", str(tmp_path / "out"))
        assert_clean_error(res, "--fraction")
        assert not (tmp_path / "out").exists()


def test_no_chained_reaches_every_arm_and_keeps_the_default_keys():
    """`--no-chained` trains every arm's model without chained Followers (they are scored on
    3-robot folds, where only the first module runs); the default keys stay those of the
    models already cached."""
    chains = np.zeros((4, 16, 3, 3))
    for chained in (True, False):
        config = replace(PROFILES["quick"], chained=chained)
        tasks = [sim2real._arm_task(arm, config, 0, chains, chains, chains, None, None)
                 for arm in ("real", "finetune")]
        assert all(t.train_config().chained is chained for t in tasks)
    plain = sim2real.ModelTask("real", 0, 2, chains, chains, chains)
    assert plain.key() == sim2real.ModelTask("real", 0, 2, chains, chains, chains,
                                             chained=True).key()
    assert plain.key() != sim2real.ModelTask("real", 0, 2, chains, chains, chains,
                                             chained=False).key()
