"""The claims rule on made-up results whose verdicts are known, and `macrostate-mj claims` on
the committed ones: one line and exit 2 on a folder it cannot judge."""

import json
from pathlib import Path

import pytest
from clitools import cli_inprocess
from conftest import REPO

from macrostate_mj.app.claims import VERDICTS, ClaimsError, judge_all

CLAIMS = """
[[t]]
figure = "value in"
claim = "ours is 2, give or take 2"
text_value = 2
margin = 2
kind = "value"
ours = "runs(good/*/r.json, x)"
folder = "good"

[[t]]
figure = "value too wide"
claim = "ours is 2, give or take 10 %"
text_value = 2
kind = "value"
ours = "runs(good/*/r.json, x)"
folder = "good"

[[t]]
figure = "value out"
claim = "ours is 10"
text_value = 10
kind = "value"
ours = "runs(good/*/r.json, x)"
folder = "good"

[[t]]
figure = "one unit"
claim = "ours is 2"
text_value = 2
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
        '[good]\nkind = "result: 5 seeds"\ncommand = "c"\nunits = 5\n\n'
        '[one]\nkind = "smoke: one seed"\ncommand = "c"\nunits = 1\n')
    (root / "claims.toml").write_text(CLAIMS)
    return root


def test_each_verdict_follows_the_rule(tmp_path):
    root = _results(tmp_path)
    got = {j.figure: j for j in judge_all(root, claims_file=root / "claims.toml")}
    assert got["value in"].verdict == "agree" and got["value in"].lo < 2 < got["value in"].hi
    wide = got["value too wide"]
    assert wide.verdict == "inconclusive" and "too wide" in wide.why and wide.would_decide > 100
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
