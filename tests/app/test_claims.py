"""The claims rule on made-up results whose verdicts are known, and `macrostate-mj claims` on
the committed ones: one line and exit 2 on a folder it cannot judge."""

import json
from pathlib import Path

import numpy as np
import pytest
from clitools import cli_inprocess
from conftest import REPO

from macrostate_mj.app.results.claims import VERDICTS, ClaimsError, judge_all, margin_verdict

CLAIMS = """
[[t]]
figure = "value in"
claim = "ours is 3, give or take 3"
text_value = 3
margin = 3
kind = "value"
ours = "runs(good/*/r.json, x)"
folder = "good"

[[t]]
figure = "value too wide"
claim = "ours is 2, give or take 10 %"
text_value = 2
metric = "cm"
kind = "value"
ours = "runs(good/*/r.json, x)"
folder = "good"

[[t]]
figure = "value out"
claim = "ours is 10"
text_value = 10
metric = "cm"
kind = "value"
ours = "runs(good/*/r.json, x)"
folder = "good"

[[t]]
figure = "one unit"
claim = "ours is 2"
text_value = 2
metric = "cm"
kind = "value"
ours = "runs(one/*/r.json, x)"
folder = "one"

[[t]]
figure = "paired order"
claim = "x below y"
kind = "ordering"
ours = "runs(good/*/r.json, x)"
order = [["ours", "<", "runs(good/*/r.json, y)", "y"]]
folder = "good"

[[t]]
figure = "paired reverse"
claim = "y below x"
kind = "ordering"
ours = "runs(good/*/r.json, y)"
order = [["ours", "<", "runs(good/*/r.json, x)", "x"]]
folder = "good"

[[t]]
figure = "composite"
claim = "x below y and below z at every step"
kind = "ordering"
ours = "runs(good/*/r.json, x)"
steps = [1, 3]
order = [["ours", "<", "runs(good/*/r.json, y)", "y"],
         ["ours", "<", "runs(good/*/r.json, z)", "z"]]
folder = "good"

[[t]]
figure = "welch"
claim = "a above 0 and above b"
kind = "ordering"
ours = "meanstd(good/s.json, a)"
order = [["ours", ">", 0, "zero"], ["ours", ">", "meanstd(good/s.json, b)", "b"]]
folder = "good"

[[t]]
figure = "elsewhere"
claim = "x below y, on other data"
kind = "ordering"
ours = "runs(good/*/r.json, x)"
order = [["ours", "<", "runs(good/*/r.json, y)", "y"]]
folder = "good"
not_comparable = "the text's data are not ours"
"""


def _results(root: Path) -> Path:
    """Five seeds where y = x + 1 exactly (paired: certain), z = x + noise that leans the
    wrong way by a little (p between .05/k and .05), and a one-seed folder."""
    x = [1.0, 2.0, 3.0, 4.0, 5.0]
    z_minus_x = [-0.2, 0.1, -0.25, 0.05, -0.2]
    for i, xi in enumerate(x):
        (root / "good" / f"s{i}").mkdir(parents=True)
        (root / "good" / f"s{i}" / "r.json").write_text(
            json.dumps({"x": xi, "y": xi + 1 + 0.01 * i, "z": xi + z_minus_x[i]}))
    (root / "good" / "s.json").write_text(json.dumps(
        {"a": {"mean": 1.0, "std": 0.5, "n": 5}, "b": {"mean": 0.9, "std": 0.5, "n": 5}}))
    (root / "one" / "s0").mkdir(parents=True)
    (root / "one" / "s0" / "r.json").write_text(json.dumps({"x": 2.0}))
    (root / "index.toml").write_text(
        '[good]\nkind = "result: 5 seeds"\ncommand = "c"\nunits = 5\nunit = "seed"\n\n'
        '[one]\nkind = "smoke: one seed"\ncommand = "c"\nunits = 1\nunit = "seed"\n')
    (root / "claims.toml").write_text(CLAIMS)
    return root


def test_each_verdict_follows_the_rule(tmp_path):
    root = _results(tmp_path)
    got = {j.figure: j for j in judge_all(root, claims_file=root / "claims.toml")}
    assert got["value in"].verdict == "agree" and 0 < got["value in"].lo < got["value in"].hi < 6
    wide = got["value too wide"]
    assert wide.verdict == "inconclusive" and "straddles" in wide.why and wide.would_decide > 5
    assert got["value out"].verdict == "disagree"
    assert got["one unit"].verdict == "inconclusive" and got["one unit"].smoke
    assert got["paired order"].verdict == "agree" and not got["paired order"].smoke
    assert got["paired reverse"].verdict == "disagree"
    # z leans above x at p < .05 one-sided, but not at .05 / 2: one comparison undecided
    composite = got["composite"]
    assert composite.verdict == "inconclusive" and "1 of 2 undecided (z)" in composite.why
    assert composite.would_decide and composite.would_decide > 5
    # Welch from mean/std/n: a is above 0 but not detectably above b
    assert got["welch"].verdict == "inconclusive" and "(b)" in got["welch"].why
    elsewhere = got["elsewhere"]
    assert elsewhere.verdict == "not comparable" and "the rule says agree" in elsewhere.why
    assert set(j.verdict for j in got.values()) <= set(VERDICTS)


def test_a_folder_that_cannot_be_judged_is_one_clear_error(tmp_path):
    root = _results(tmp_path)
    (root / "good" / "s.json").write_text("{ half")
    with pytest.raises(ClaimsError, match="cannot read .*s.json"):
        judge_all(root, claims_file=root / "claims.toml")
    (root / "good" / "s.json").unlink()
    with pytest.raises(ClaimsError, match="s.json does not exist"):
        judge_all(root, claims_file=root / "claims.toml")
    with pytest.raises(ClaimsError, match="no index.toml"):
        judge_all(tmp_path / "good")
    with pytest.raises(ClaimsError, match="no chapter 'chapter9'"):
        judge_all(REPO / "results", ["chapter9"])


def test_claims_command_prints_one_object_per_claim(capsys):
    code, out, _ = cli_inprocess(capsys, "claims", "--results", str(REPO / "results"), "--json")
    rows = [json.loads(line) for line in out.splitlines()]
    keys = {"chapter", "figure", "claim", "text_value", "ours", "lo", "hi", "n", "kind",
            "verdict", "folder"}
    assert code == 0 and len(rows) == 37 and all(keys <= set(r) for r in rows)
    assert {r["kind"] for r in rows} <= {"value", "ordering", "qualitative"}
    for r in rows:                     # an interval holds its mean
        assert r["lo"] is None or r["lo"] <= r["ours"] <= r["hi"], r["figure"]


@pytest.mark.parametrize("args,says", [
    (("--results", "/nonexistent/results"), "/nonexistent/results"),
    (("--results", "examples"), "no index.toml"),
    (("--chapter", "chapter9"), "chapter9")])
def test_claims_bad_input_is_one_line_and_exit_2(capsys, monkeypatch, args, says):
    monkeypatch.chdir(REPO)
    code, out, err = cli_inprocess(capsys, "claims", *args)
    assert code == 2 and says in err and len(err.strip().splitlines()) == 1 and not out


@pytest.mark.parametrize("lo,hi,verdict", [
    (0.770, 0.800, "agree"),          # inside 0.786 ± 0.02
    (0.700, 0.760, "disagree"),       # wholly below 0.766
    (0.810, 0.850, "disagree"),       # wholly above 0.806
    (0.750, 0.790, "inconclusive"),   # across the lower edge
    (0.687, 0.810, "inconclusive"),   # wider than the band, holding it
])
def test_the_margin_rule_has_three_outcomes_on_both_sides(lo, hi, verdict):
    assert margin_verdict(lo, hi, 0.786, 0.02) == verdict


NESTED = """
[[t]]
figure = "nested value"
claim = "ours is 0.75"
text_value = 0.75
metric = "auc"
kind = "value"
ours = "oc_auc(oc, iogen)"
folder = "oc"

[[t]]
figure = "cv gain"
claim = "ours is 47 %"
text_value = 47
metric = "%"
kind = "value"
ours = "runs(cv/*/r.json, g, .0f, %)"
folder = "cv"

[[t]]
figure = "one training"
claim = "x below 5"
kind = "ordering"
ours = "runs(cv/*/r.json, g)"
order = [["ours", "<", 60, "60"]]
folder = "cv"
trainings = 1
"""


def _nested(root: Path) -> Path:
    """3 splits x 3 seeds of one-class AUCs whose seeds differ far more than their splits'
    means, and 5 overlapping folds (chapter 2's per-fold gains)."""
    runs = {f"m2_split{s}_s{k}": {"iogen": {"auc_all": 0.75 + 0.001 * s + 0.05 * (k - 1)}}
            for s in (1, 2, 3) for k in (0, 1, 2)}
    (root / "oc").mkdir(parents=True)
    from macrostate_mj.app.experiments.oc import Results as OcResults

    OcResults({}, {}, {}, {}, {}, {}, 0, {}, runs).write(root / "oc")   # only the runs matter
    for i, g in enumerate([28.275, 36.848, 37.852, 38.695, 43.212]):
        (root / "cv" / f"s{i}").mkdir(parents=True)
        (root / "cv" / f"s{i}" / "r.json").write_text(json.dumps({"g": g}))
    (root / "index.toml").write_text(
        '[oc]\nkind = "result: 3 splits x 3 seeds"\ncommand = "c"\nunits = 3\nunit = "split"\n'
        'within = "seed"\ngroup = \'split\\d+\'\nshared = "one dev set"\n\n'
        '[cv]\nkind = "result: 5 folds"\ncommand = "c"\nunits = 5\nunit = "fold"\nfolds = 5\n')
    (root / "claims.toml").write_text(NESTED)
    return root


def test_nested_runs_are_averaged_to_their_unit_and_folds_are_corrected(tmp_path):
    """Nine runs of three splits count as three units, each the mean of its seeds (the seeds'
    spread cancels: 0.751, 0.752, 0.753); five overlapping folds get Nadeau-Bengio's interval,
    [26.8, 47.1] where the plain one is [30.2, 43.7]; `claims --json` names both."""
    root = _nested(tmp_path)
    got = {j.figure: j for j in judge_all(root, claims_file=root / "claims.toml")}
    nested = got["nested value"]
    assert nested.n == 3 and nested.ours == pytest.approx(0.752)
    assert nested.hi - nested.lo < 0.01 and nested.verdict == "agree"
    assert "splits, seeds averaged within each" in nested.unit and "one dev set" in nested.unit
    cv = got["cv gain"]
    assert (round(cv.lo, 1), round(cv.hi, 1)) == (26.8, 47.1) and cv.n == 5
    assert cv.verdict == "inconclusive" and "Nadeau-Bengio" in cv.correction
    assert set(cv.as_json()) >= {"unit", "correction", "margin"}
    one = got["one training"]
    assert one.verdict == "inconclusive" and "one training" in one.why and "agree" in one.why


def test_a_nested_declaration_without_per_run_values_or_a_unit_is_refused(tmp_path):
    root = _nested(tmp_path)
    index = (root / "index.toml").read_text()
    (root / "index.toml").write_text(index.replace('unit = "fold"\n', ""))
    with pytest.raises(ClaimsError, match="declares no `unit`"):
        judge_all(root, claims_file=root / "claims.toml")
    (root / "index.toml").write_text(index.replace("group = 'split\\d+'", "group = 'fold\\d+'"))
    with pytest.raises(ClaimsError, match="names no split"):
        judge_all(root, claims_file=root / "claims.toml")


def test_resampled_splits_whose_training_sets_overlap_are_corrected_by_their_ratio():
    """Chapter 4's splits are drawn from one pool (266 test, 1,067 training ids each; about 79 %
    of training ids shared): the interval over them is Nadeau-Bengio corrected with that ratio,
    by hand: half-width t(.975, 2) * s * sqrt(1/3 + 266/1067)."""
    from scipy import stats as sps

    from macrostate_mj.app.results.claims import Design, Figure

    split = Design.of({"unit": "split", "split_ratio": 266 / 1067}, "test")
    plain = Design.of({"unit": "split"}, "test")
    values = {"split1": 0.70, "split2": 0.76, "split3": 0.79}
    fig = Figure.of(values, ".3f", "")
    lo, hi = split.apply(fig).interval()
    s = float(np.std(list(values.values()), ddof=1))
    half = sps.t.ppf(0.975, 2) * s * (1 / 3 + 266 / 1067) ** 0.5
    assert (hi - lo) / 2 == pytest.approx(half)
    assert (hi - lo) > (plain.apply(fig).interval()[1] - plain.apply(fig).interval()[0])
    assert "random splits whose training sets overlap (n_test/n_train = 0.249)" in \
        split.correction()
    assert "Nadeau-Bengio corrected" in split.says(3)
