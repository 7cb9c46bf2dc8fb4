"""`sysid`: the objective, the candidates, and a tiny fit end to end (a lab collection stands in
for the real files, so no reference data is needed)."""

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from clitools import cli

from collectors.randomize import ABSOLUTE
from macrostate_mj.app.usecases.sysid import (
    FITTED,
    SysidConfig,
    best_still,
    box,
    candidates,
    feasible,
    identity,
    point,
    score,
    values,
)
from macrostate_mj.chain.scenarios import get_scenario


def test_score_sums_per_robot_rows_and_averages_each_lag_family():
    rows = [{"feature": "speed_cm_s", "robot": "H", "ks": 0.5},
            {"feature": "speed_cm_s", "robot": "pooled", "ks": 0.9},
            {"feature": "speed_acf_lag1", "robot": "H", "ks": 0.2},
            {"feature": "speed_acf_lag2", "robot": "H", "ks": 0.4},
            {"feature": "turn_acf_lag1", "robot": "T", "ks": 0.1}]
    assert score(rows) == pytest.approx(0.5 + 0.3 + 0.1)


def test_candidates_start_from_the_scenario_and_stay_in_the_box():
    cfg = SysidConfig(first=8, refine=4)
    first = candidates(cfg)
    assert first.shape == (8, len(FITTED)) and np.array_equal(first[0], np.zeros(len(FITTED)))
    lo, hi = box()
    assert np.all((first >= lo) & (first <= hi)) and np.all(lo <= 0) and np.all(hi >= lo)
    # the box reaches past the scenario's value but where the value is already a bound: a
    # Psi Head's turn is at most 180 degrees, as written
    assert {k for k, h in zip(FITTED, hi, strict=True) if h <= 0} == {"max_turn"}
    factor = np.array([k not in ABSOLUTE for k in FITTED])
    assert np.all(lo[factor] < 0) and np.all(lo[~factor] == 0)       # 0: as the lab is written
    assert values(first[0]) == {k: (0.0 if k in ABSOLUTE else 1.0) for k in FITTED}
    assert np.allclose(point(values(first[3])), first[3], atol=1e-4)
    assert np.array_equal(first, candidates(cfg))                       # seeded
    centre = first[3]
    second = candidates(cfg, centre)
    half = cfg.shrink * (hi - lo) / 2
    assert second.shape == (4, len(FITTED)) and np.all(np.abs(second - centre) <= half + 1e-12)


def test_a_fit_is_keyed_by_the_scenario_s_content_not_its_name(tmp_path):
    """A lab file edited between two fits must not reuse the first fit's cached scores."""
    lab = tmp_path / "mylab.toml"
    lab.write_text('extends = "lab"\nname = "mylab"\n')
    before = identity(SysidConfig(scenario=get_scenario(lab)))
    lab.write_text('extends = "lab"\nname = "mylab"\n[followers]\nkind = "wait_for_behind"\n'
                   "slack = 0.05\nhold = 0.01\n")
    after = identity(SysidConfig(scenario=get_scenario(lab)))
    assert before["scenario"] == after["scenario"] == "mylab"
    assert before["scenario_hash"] != after["scenario_hash"]


def test_a_tiny_fit_end_to_end(tmp_path):
    stand_in = tmp_path / "stand_in"
    res = cli("collect", "--scenario", "lab", "--robots", "3", "--minutes", "2", "--seed", "9",
              "--split", "50/50/0", "--out", str(stand_in))
    assert res.returncode == 0, res.stderr
    out = tmp_path / "fit"
    args = ["sysid", "--train", str(stand_in / "Train.csv"), "--val", str(stand_in / "Val.csv"),
            "--minutes", "1", "--first", "2", "--refine", "1"]
    res = cli(*args, "--out", str(out))
    assert res.returncode == 0, res.stderr
    fit = json.loads((out / "fit.json").read_text())
    assert len(fit["candidates"]) == 3
    assert fit["train"]["after"] == min(c["score"] for c in fit["candidates"])
    assert fit["train"]["after"] <= fit["train"]["before"]
    assert set(fit["val"]) == {"before", "after"}
    res = cli("collect", "--minutes", "0.5", "--randomize", str(out / "fitted.json"),
              "--out", str(tmp_path / "fitted_lab"))
    assert res.returncode == 0, res.stderr
    res = cli(*args, "--robots", "5", "--out", str(tmp_path / "bad"))
    assert res.returncode == 2 and "robots" in res.stderr and res.stderr.count("\n") == 1
    assert not (tmp_path / "bad").exists()
    # a fit moved elsewhere resumes there from its cache: nothing is collected again, and its
    # candidates are read from where they now are
    moved = tmp_path / "moved"
    shutil.move(out, moved)
    res = cli(*args, "--out", str(moved), "--overwrite")
    assert res.returncode == 0, res.stderr
    again = json.loads((moved / "fit.json").read_text())
    assert again["train"] == fit["train"] and again["val"] == fit["val"]
    assert all(Path(c["folder"]).parent == moved / "candidates" for c in again["candidates"])


def test_the_timed_profile_is_the_committed_fit():
    """`wider-rear-timed` is results/sysid_timing2's fitted.json (`wider-rear`'s ranges around
    the fitted timing), the profile the sealed look of the recipe drew."""
    from collectors.randomize import PROFILES

    committed = Path(__file__).resolve().parents[2] / "results" / "sysid_timing2"
    fitted = json.loads((committed / "fitted.json").read_text())
    assert json.loads(json.dumps(PROFILES["wider-rear-timed"])) == fitted


def test_the_refit_profile_is_the_committed_fit():
    """`--randomize refit` holds the factors `results/sysid_refit` fitted, not a copy that
    drifts from them."""
    from pathlib import Path

    from collectors.randomize import REFIT

    fitted = Path(__file__).resolve().parents[2] / "results" / "sysid_refit" / "fitted.json"
    assert REFIT == json.loads(fitted.read_text())


def test_the_fit_keeps_only_candidates_whose_parked_chain_stands_still():
    """The best score loses to a worse one whose parked chain stands still; with none still
    the fit stops in one line."""
    moving = {"score": 1.0, "parked": {"still": False}, "factors": {"k_f": 9.0}}
    still = {"score": 2.0, "parked": {"still": True}, "factors": {"k_f": 1.0}}
    assert best_still([moving, still]) is still
    with pytest.raises(ValueError, match="none of 1 candidates parks its chain still"):
        best_still([moving])


def test_a_fit_of_some_parameters_within_a_recipe_s_ranges_checked_on_train_s_end(tmp_path):
    """`--only`: the others keep the scenario's values (a smaller box); `--base`: each
    candidate drawn within the recipe's ranges around its factors; no `--val`: the fit leaves
    the Train file's last 15 % out and is checked on it. A full fit's keys stay as they were;
    an alternation the frames have no room for is capped, not refused mid-fit."""
    cfg = SysidConfig(only=("marker_jitter", "frame_alternation"), base="wider-rear")
    assert cfg.fitted == ("marker_jitter", "frame_alternation")
    assert candidates(cfg).shape == (16, 2)
    profile = cfg.profile({"marker_jitter": 0.8, "frame_alternation": 0.05})
    assert profile["marker_jitter"] == pytest.approx((0.56, 1.12))
    assert profile["frame_alternation"] == 0.05 and profile["follow_hold"] == 0.3
    assert "only" not in identity(SysidConfig()) and "base" not in identity(SysidConfig())
    assert identity(cfg)["base"]["follow_hold"] == 0.3
    lab = get_scenario("lab")
    assert feasible({"frame_alternation": 0.09, "frame_hz": 1.6, "frame_jitter": 0.1}, lab)[
        "frame_alternation"] == pytest.approx(0.95 * (1 / 6.4 - 0.1), abs=1e-4)
    assert feasible({"frame_alternation": 0.05}, lab) == {"frame_alternation": 0.05}
    with pytest.raises(Exception, match="--only"):
        SysidConfig(only=("nonsense",))
    stand_in = tmp_path / "stand_in"
    res = cli("collect", "--scenario", "lab", "--robots", "3", "--minutes", "2", "--seed", "9",
              "--split", "100/0/0", "--out", str(stand_in))
    assert res.returncode == 0, res.stderr
    res = cli("sysid", "--train", str(stand_in / "Train.csv"), "--only", "frame_alternation",
              "--base", "wider-rear", "--minutes", "1", "--first", "2", "--refine", "1",
              "--out", str(tmp_path / "fit"))
    assert res.returncode == 0, res.stderr
    assert "on the last 15% of Train.csv" in res.stdout
    profile = json.loads((tmp_path / "fit" / "fitted.json").read_text())
    fit = json.loads((tmp_path / "fit" / "fit.json").read_text())
    assert set(fit["fitted"]) == {"frame_alternation"}       # within the recipe's ranges
    assert profile == {**json.loads(json.dumps(cfg.profile({}))), **fit["fitted"]}
    res = cli("sysid", "--train", str(stand_in / "Train.csv"), "--only", "nonsense",
              "--out", str(tmp_path / "bad"))
    assert res.returncode == 2 and "--only nonsense" in res.stderr
    assert not (tmp_path / "bad").exists()
