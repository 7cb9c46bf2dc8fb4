"""`experiment s2r-sealed`: the sealed test takes part in no choice, a look needs a frozen
recipe and is counted once, the quarters go round the pool, and a quick end-to-end run (a
small lab collection stands in for the real files)."""

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from clitools import cli

from macrostate_mj.app.experiments import execute, s2r_sealed
from macrostate_mj.app.experiments.sim2real import share
from macrostate_mj.core.errors import UserError
from macrostate_mj.core.stats import two_level_bootstrap

FROZEN = {"commit": "0" * 40, "dirty": False, "digest": "d"}


def _config(stand_in: Path, tmp: Path, **changes) -> s2r_sealed.Config:
    return replace(s2r_sealed.PROFILES["quick"], real=stand_in, ledger=tmp / "ledger.jsonl",
                   **changes)


def test_quick_run_scores_the_sealed_test_and_counts_one_look(stand_in, tmp_path,
                                                              monkeypatch):
    monkeypatch.setattr(s2r_sealed, "code", lambda: FROZEN)
    config = _config(stand_in, tmp_path)
    lines = execute("s2r-sealed", config, tmp_path / "out", workers=2)
    results = json.loads((tmp_path / "out" / "results.json").read_text())
    n_sealed = len(s2r_sealed.read_csv(stand_in / "Val.csv").poses)
    assert results["instances"] == n_sealed and set(results["arms"]) == set(s2r_sealed.ARMS)
    for arm, cell in results["against_real"].items():
        ratio = cell["ratio"]
        assert ratio["low"] <= ratio["mean"] <= ratio["high"], arm
        assert ratio["mean"] == pytest.approx(results["arms"][arm]["head_cm"]["mean"]
                                              / results["arms"]["real"]["head_cm"]["mean"])
    parts = results["arms"]["quarter"]["parts"]        # two seeds, two different quarters
    assert parts["0"][0] == 0 and parts["1"][0] > 0
    assert {b - a for a, b in parts.values()} == {int(np.ceil(results["pool_instances"] / 4))}
    begun, entry = [json.loads(x) for x in config.ledger.read_text().splitlines()]
    assert begun["event"] == "begun" and begun["recipe_hash"] == results["recipe_hash"]
    assert entry["looks"] == 1 and not entry["repeat"] and not entry["code_changed"]
    assert entry["recipe_hash"] == results["recipe_hash"]
    assert "look 1 of 1 in the ledger" in lines[0] and entry["look"] == 1


def test_looks_count_the_sealed_scores_seen_at_this_sealed_file(stand_in, tmp_path,
                                                              monkeypatch):
    """A rescore of the same models is a repeat (whatever else changed); other scores are a
    new look; a look begun and never finished counts (its scores may have been read), unless
    the same recipe finished at that commit; another sealed file's looks are not this one's."""
    monkeypatch.setattr(s2r_sealed, "code", lambda: FROZEN)

    config = _config(stand_in, tmp_path)
    rec = s2r_sealed.recipe(config)

    def scored(errors):
        return {"against_real": {"lab": {"ratio": {"mean": 1.4, "low": 1.2, "high": 1.6}}},
                "arms": {"lab": {"head_cm": {"mean": 5.0},
                                 "head_cm_by_instance": {"0": errors}}},
                "recipe": rec, "recipe_hash": s2r_sealed.config_hash(rec)}

    s2r_sealed.begin(config, FROZEN, rec)
    first = s2r_sealed.look(config, scored([1.0, 2.0]), FROZEN)
    again = s2r_sealed.look(replace(config, randomize="wider"), scored([1.0, 2.0]), FROZEN)
    other = s2r_sealed.look(config, scored([1.0, 2.5]), FROZEN)
    assert (first["looks"], again["looks"], other["looks"]) == (1, 1, 2)
    assert (first["look"], again["look"], other["look"]) == (1, 1, 2)
    assert (first["repeat"], again["repeat"], other["repeat"]) == (False, True, False)
    other_recipe = s2r_sealed.recipe(replace(config, seeds=3))
    s2r_sealed.begin(config, FROZEN, other_recipe)              # interrupted: never finished
    entries = s2r_sealed.ledger_entries(config.ledger)
    assert len(entries) == 5 and s2r_sealed.looks(entries, first["sealed"]) == 3
    assert s2r_sealed.looks(entries, "another sealed file") == 0
    config.ledger.write_text(config.ledger.read_text() + "not json\n")
    with pytest.raises(UserError, match="--ledger"):
        s2r_sealed.validate(config)


def test_a_look_is_refused_unless_frozen_and_deliberate(stand_in, tmp_path,
                                                                 monkeypatch):
    monkeypatch.setattr(s2r_sealed, "code", lambda: FROZEN)
    for bad, named in (({"seeds": 1}, "seeds"), ({"epochs": 2.5}, "epochs"),
                       ({"select_share": 1.0}, "select_share"), ({"finetune_lr": -1}, "lr"),
                       ({"select_share": 0.99}, "pool"),
                       ({"randomize": "nonsense"}, "nonsense")):
        with pytest.raises(UserError, match=named):          # from Python, as from the CLI
            s2r_sealed.validate(replace(_config(stand_in, tmp_path), **bad))
    for unfrozen in ({**FROZEN, "dirty": True}, {**FROZEN, "commit": None, "dirty": None}):
        monkeypatch.setattr(s2r_sealed, "code", lambda made=unfrozen: made)
        with pytest.raises(UserError, match="frozen recipe"):     # git could not tell, too
            s2r_sealed.validate(_config(stand_in, tmp_path))
    res = cli("experiment", "all", "--quick", "--only", "s2r-sealed", "--out",
              str(tmp_path / "all"))
    assert res.returncode == 2 and "sealed test" in res.stderr
    assert not (tmp_path / "all").exists()
    res = cli("experiment", "s2r-sealed", "--quick", "--real", str(tmp_path), "--out",
              str(tmp_path / "out"), "--ledger", str(tmp_path / "l.jsonl"))
    assert res.returncode == 2 and "Train.csv" in res.stderr
    assert not (tmp_path / "out").exists() and not (tmp_path / "l.jsonl").exists()


def test_the_sealed_test_picks_no_checkpoint_and_trains_nothing(stand_in, tmp_path):
    config = replace(_config(stand_in, tmp_path), seeds=4)
    train = np.arange(40.0).reshape(40, 1)
    pool, check, sealed = train[:34], train[34:], np.full((5, 1), -1.0)
    sims = {s: tmp_path / f"{s}.pt" for s in range(4)}
    tasks = s2r_sealed._tasks(config, tmp_path, pool, check, sealed, None) + \
        s2r_sealed._tasks(config, tmp_path, pool, check, sealed, sims)
    assert len(tasks) == 4 * len(s2r_sealed.ARMS)
    for meta, task in tasks:
        assert task.val is check and task.test is sealed, meta
        if isinstance(task.train, np.ndarray):
            assert not np.isin(task.train, sealed).any() and not np.isin(task.train, check).any()
    quarters = [t.train.ravel() for m, t in tasks if m["arm"] == "quarter"]
    assert set(np.concatenate(quarters)) == set(pool.ravel())     # the four quarters in turn


def test_the_quarters_go_round_the_pool():
    assert [share(230, 0.25, i) for i in range(5)] == [
        slice(0, 58), slice(57, 115), slice(115, 173), slice(172, 230), slice(0, 58)]
    assert share(230, 1.0, 3) == slice(0, 230) and share(10, 0.1, 9) == slice(9, 10)


def test_the_bootstrap_covers_the_ratio_and_widens_with_fewer_instances():
    rng = np.random.default_rng(0)
    ref = 4.0 + rng.normal(0, 1.0, (4, 200))
    arm = 1.5 * ref + rng.normal(0, 0.2, (4, 200))
    wide = two_level_bootstrap(arm[:, :20], ref[:, :20])["ratio"]
    narrow = two_level_bootstrap(arm, ref)["ratio"]
    assert narrow["low"] < 1.5 < narrow["high"]
    assert narrow["high"] - narrow["low"] < wide["high"] - wide["low"]
    with pytest.raises(ValueError):
        two_level_bootstrap(arm[:, :3], ref[:, :4])
    with pytest.raises(ValueError):
        two_level_bootstrap(arm[0], ref[0])               # one seed's row is not a table
