"""`stats --compare`: motion distributions of two ThymioLoc files and their KS distances."""

import json

import numpy as np
import pytest
from clitools import cli_inprocess as _cli

from estimators.retlo.files import world_to_pixels
from estimators.retlo.synthetic import synthetic_chains
from macrostate_mj.core.errors import UserError
from macrostate_mj.formats import motion_stats
from macrostate_mj.formats.thymioloc import write_csv


def _file(tmp_path, name, n_robots=3, seed=0, n_inst=20, jitter=0.0):
    world = synthetic_chains(n_inst, n_robots, seed)
    world[..., :2] += np.random.default_rng(seed).normal(0, jitter, world[..., :2].shape)
    return write_csv(tmp_path / name, world_to_pixels(world, 3.0))


def test_a_file_against_itself_has_zero_distance_everywhere(tmp_path, capsys):
    a = _file(tmp_path, "a.csv")
    code, out, err = _cli(capsys, "stats", "--compare", str(a), str(a), "--json")
    assert code == 0, err
    rows = [json.loads(line) for line in out.splitlines()]
    features = {r["feature"] for r in rows}
    assert {"spacing_cm", "speed_cm_s", "jitter_cm", "wait_share", "speed_acf_lag10",
            "turn_acf_lag1"} <= features
    assert all(r["ks"] == 0 for r in rows) and {r["robot"] for r in rows} >= {"H", "T", "pooled"}


def test_tracker_jitter_is_what_separates_a_noisy_copy(tmp_path, capsys):
    """The same chains with 1 cm of position noise: jitter differs most, spacing barely."""
    clean, noisy = _file(tmp_path, "c.csv"), _file(tmp_path, "n.csv", jitter=0.01)
    code, out, _ = _cli(capsys, "stats", "--compare", str(clean), str(noisy), "--json",
                        "--plot", str(tmp_path / "cmp.png"))
    assert code == 0
    pooled = {r["feature"]: r for r in map(json.loads, out.splitlines()) if r["robot"] == "pooled"}
    assert pooled["jitter_cm"]["ks"] > 0.5 and pooled["jitter_cm"]["median"][1] > pooled[
        "jitter_cm"]["median"][0]
    assert pooled["jitter_cm"]["ks"] > pooled["spacing_cm"]["ks"]
    assert (tmp_path / "cmp.png").stat().st_size > 10_000


def test_files_that_do_not_compare_are_refused(tmp_path, capsys):
    three, five = _file(tmp_path, "3.csv"), _file(tmp_path, "5.csv", n_robots=5)
    for args, words in ((["--compare", str(three), str(five)], "same team size"),
                        (["--compare", str(three)], "exactly two files"),
                        ([str(three), "--plot", str(tmp_path / "p.png")], "need --compare")):
        code, _, err = _cli(capsys, "stats", *args)
        assert code == 2 and err.count("\n") == 1 and words in err, err
    assert not (tmp_path / "p.png").exists()
    with pytest.raises(UserError, match="too short"):
        motion_stats.features(np.zeros((2, 8, 3, 3)), 3.0)


def test_the_ranked_gap_puts_the_statistic_that_differs_first(tmp_path, capsys):
    """1 cm of tracker noise on one copy: the frame-to-frame jitter ranks first, with the lab
    parameters that shape it beside it; an autocorrelation's ten lags are one statistic; the
    table and --json say the same."""
    from collectors.gap import SHAPED_BY

    clean, noisy = _file(tmp_path, "c.csv"), _file(tmp_path, "n.csv", jitter=0.01)
    code, out, err = _cli(capsys, "stats", "--compare", str(clean), str(noisy), "--rank",
                          "--json")
    assert code == 0, err
    ranked = [json.loads(line) for line in out.splitlines()]
    assert ranked[0]["statistic"] == "jitter_cm" and "marker_jitter" in ranked[0]["shaped_by"]
    assert {r["statistic"] for r in ranked} == set(SHAPED_BY)        # every one, lags as one
    worst = [r["ks"][r["worst"]] for r in ranked]
    assert worst == sorted(worst, reverse=True)
    assert all(r["sum"] == pytest.approx(sum(r["ks"].values())) for r in ranked)
    assert set(ranked[0]["ks"]) == {"H", "F1", "T"} and "pooled" not in ranked[0]["ks"]
    spacing = next(r for r in ranked if r["statistic"] == "spacing_cm")
    assert set(spacing["ks"]) == {"H-F1", "F1-T"}
    code, table, _ = _cli(capsys, "stats", "--compare", str(clean), str(noisy), "--rank")
    assert code == 0 and table.index("jitter_cm") < table.index("spacing_cm")
    code, _, err = _cli(capsys, "stats", str(clean), "--rank")
    assert code == 2 and "need --compare" in err and err.count("\n") == 1


def test_the_ranked_gap_shows_what_each_modelled_difference_does_to_the_estimator(tmp_path,
                                                                                    capsys):
    """`--effects`: a sim2real run's ablations beside every statistic a switched-off group
    shapes (a group shaping none is not shown); a file without ablations, or --effects
    without --rank, is one line."""
    clean, noisy = _file(tmp_path, "c.csv"), _file(tmp_path, "n.csv", jitter=0.01)
    run = tmp_path / "results.json"
    cell = {"mean": 0.4, "low": -0.1, "high": 0.9, "n": 5}
    run.write_text(json.dumps({"profile": {}, "real_instances": 0, "arms": {},   # a record
                               "ablations": {"frame_hz,frame_jitter": {"minus_lab": cell},
                                             "follow_hold": {"minus_lab": cell}}}))
    code, out, err = _cli(capsys, "stats", "--compare", str(clean), str(noisy), "--rank",
                          "--json", "--effects", str(run))
    assert code == 0, err
    ranked = {r["statistic"]: r for r in map(json.loads, out.splitlines())}
    assert ranked["jitter_cm"]["effects"] == {"frame_hz,frame_jitter": cell}
    assert ranked["spacing_cm"]["effects"] == {}
    code, table, _ = _cli(capsys, "stats", "--compare", str(clean), str(noisy), "--rank",
                          "--effects", str(run))
    assert code == 0 and "+0.40 [-0.10, +0.90]" in table
    bare = tmp_path / "bare.json"
    bare.write_text("{}")
    for args, words in ((["--rank", "--effects", str(bare)], "no ablations"),
                        (["--effects", str(run)], "add --rank")):
        code, _, err = _cli(capsys, "stats", "--compare", str(clean), str(noisy), *args)
        assert code == 2 and words in err and err.count("\n") == 1, err
