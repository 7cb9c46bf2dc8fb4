"""`collect`: instances, ThymioLoc layout, determinism across workers and Ray, kill and resume."""

import json
import os
import signal
import subprocess
import sys
import time
from dataclasses import replace

import numpy as np
import pytest
from clitools import assert_clean_error, cli

from macrostate_mj.formats.instances import instance_starts, split_indices, to_thymioloc_pixels
from macrostate_mj.formats.thymioloc import read_csv

TINY = ["--robots", "3", "--minutes", "0.75", "--episode-minutes", "0.25", "--seed", "5"]


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    out = tmp_path_factory.mktemp("ref")
    res = cli("collect", *TINY, "--workers", "1", "--split", "60/10/30", "--out", str(out))
    assert res.returncode == 0, res.stderr
    return out


def test_instances_are_26_steps_at_least_7_s_apart():
    starts = instance_starts(600, 2.0, first=20)
    assert starts[0] == 20
    gaps_s = (np.diff(starts) - 25) / 2.0
    assert np.all(gaps_s >= 7.0) and np.all(gaps_s < 7.5)
    assert starts[-1] + 26 <= 600
    assert len(instance_starts(600, 2.0)) == 15          # 5 min: 31 of them give 465


def test_thymioloc_pixel_conventions():
    arena = (2.5, 1.9)
    poses = np.array([[-1.25, 0.95, 0.0], [1.25, -0.95, np.pi / 2], [0, 0, -np.pi / 2]])
    px = to_thymioloc_pixels(poses, arena, 3.0)
    assert np.allclose(px[0], [0, 0, 0])                 # top-left corner, facing right
    assert np.allclose(px[1], [750, 570, 90])            # facing world +y = image up: o = 90
    assert np.allclose(px[2], [375, 285, -90])


def test_split_is_a_seeded_partition():
    parts = split_indices(100, (60, 10, 30), np.random.default_rng(0))
    assert [len(p) for p in parts] == [60, 10, 30]
    assert sorted(np.concatenate(parts).tolist()) == list(range(100))


def test_collect_writes_thymioloc_truth_splits_and_manifest(reference):
    tracked = read_csv(reference / "instances.csv")
    truth = read_csv(reference / "instances_truth.csv")
    assert tracked.poses.shape == truth.poses.shape == (3, 26, 3, 3)   # one per episode
    diff = np.abs(tracked.poses[..., :2] - truth.poses[..., :2])
    assert 0 < np.median(diff) <= 3                      # tracked, not a copy of the truth
    assert tracked.poses[..., 0].min() >= 0 and tracked.poses[..., 0].max() <= 750
    sizes = [read_csv(reference / f"{s}.csv").n_instances for s in ("Train", "Test")]
    assert sum(sizes) + (read_csv(reference / "Val.csv").n_instances
                         if (reference / "Val.csv").exists() else 0) == 3
    manifest = json.loads((reference / "manifest.json").read_text())
    assert manifest["px_per_cm"] == 3.0 and manifest["config"]["episodes"] == 3


def test_worker_count_does_not_change_the_csv(reference, tmp_path):
    res = cli("collect", *TINY, "--workers", "2", "--split", "60/10/30", "--out", str(tmp_path))
    assert res.returncode == 0, res.stderr
    for name in ("instances.csv", "instances_truth.csv", "Train.csv", "Test.csv"):
        assert (tmp_path / name).read_bytes() == (reference / name).read_bytes()


def test_ray_gives_the_same_csv(reference, tmp_path):
    pytest.importorskip("ray")
    res = cli("collect", *TINY, "--ray", "local", "--split", "60/10/30", "--out", str(tmp_path))
    assert res.returncode == 0, res.stderr
    assert (tmp_path / "instances.csv").read_bytes() == (reference / "instances.csv").read_bytes()


def test_sigkill_then_same_command_resumes_without_loss(reference, tmp_path):
    args = [sys.executable, "-m", "macrostate_mj.app.cli", "collect", *TINY, "--split", "60/10/30",
            "--out", str(tmp_path)]
    proc = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True)
    deadline = time.time() + 300
    while not _episodes(tmp_path) and time.time() < deadline and proc.poll() is None:
        time.sleep(0.2)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    assert _episodes(tmp_path) and not (tmp_path / "instances.csv").exists()
    shard = _episodes(tmp_path)[0]
    kept = shard.stat().st_mtime_ns
    res = cli(*args[3:])
    assert res.returncode == 0, res.stderr
    assert shard.stat().st_mtime_ns == kept              # finished work is not redone
    manifest = json.loads((tmp_path / "manifest.json").read_text())
    assert manifest["resumed_episodes"] >= 1
    for name in ("instances.csv", "instances_truth.csv", "Train.csv"):
        assert (tmp_path / name).read_bytes() == (reference / name).read_bytes()


@pytest.mark.parametrize("args,words", [
    (["--policy", "wild"], ["wild", "passive"]),
    (["--split", "60/40"], ["--split"]),
    (["--minutes", "0"], ["positive"]),
    (["--minutes", "0.1"], ["too short"]),
    (["--workers", "0"], ["--workers"]),
    (["--ray", "127.0.0.1:1"], ["Ray", "127.0.0.1:1"]),
])
def test_bad_input_one_line_exit_2_nothing_written(tmp_path, args, words):
    base = ["--robots", "3", "--minutes", "1"]
    out = tmp_path / "never"
    assert_clean_error(cli("collect", "--out", str(out), *base, *args), *words)
    assert not out.exists()


@pytest.mark.parametrize("field,value,words", [
    ("seed", -3, "seed must be a whole number >= 0"),
    ("minutes", float("nan"), "minutes must be a finite number above 0"),
    ("robots", 1, "at least 2"),
])
def test_bad_values_from_python_are_refused_before_anything_is_written(tmp_path, field, value,
                                                                      words):
    from collectors.runner import CollectRequest, collect
    from macrostate_mj.core.errors import UserError

    request = {"scenario": "lab", "robots": 3, "minutes": 1.0, "seed": 0,
               "out": tmp_path / "never", field: value}
    with pytest.raises(UserError, match=words):
        collect(CollectRequest(**request))
    assert not (tmp_path / "never").exists()


def test_stats_prints_our_dataset_beside_real_data(reference, reference_data):
    real = reference_data / "ReTLo" / "Datasets" / "3Robots" / "Train.csv"
    res = cli("stats", str(reference / "instances.csv"), str(real))
    assert res.returncode == 0, res.stderr
    assert "instances.csv" in res.stdout and "Train.csv" in res.stdout


def test_a_damaged_shard_is_simulated_again(reference, tmp_path):
    """A shard truncated by something outside the run (disk full, a copy cut short) is not
    finished work: the rerun simulates that episode again and the datasets come out the same."""
    import shutil

    args = ["collect", *TINY, "--split", "60/10/30", "--out", str(tmp_path)]
    shutil.copytree(reference / "cache", tmp_path / "cache")
    damaged = _episodes(tmp_path)[1]
    damaged.write_bytes(damaged.read_bytes()[:100])
    res = cli(*args)
    assert res.returncode == 0, res.stderr
    manifest = json.loads((tmp_path / "manifest.json").read_text())
    assert len(manifest["damaged_shards_rerun"]) == 1 and manifest["resumed_episodes"] == 2
    assert (tmp_path / "instances.csv").read_bytes() == (reference / "instances.csv").read_bytes()


def test_an_unfinished_run_of_another_collection_is_refused_then_overwritten(tmp_path):
    from macrostate_mj.core.run import Run

    with pytest.raises(KeyboardInterrupt), Run(tmp_path, "collect", {"other": 1}, 0):
        raise KeyboardInterrupt          # an earlier collection, stopped
    args = ["collect", "--robots", "3", "--minutes", "0.25", "--seed", "1", "--out",
            str(tmp_path)]
    assert_clean_error(cli(*args), "unfinished", "--overwrite")
    assert json.loads((tmp_path / "manifest.json").read_text())["status"] == "interrupted"
    res = cli(*args, "--overwrite")
    assert res.returncode == 0, res.stderr
    assert json.loads((tmp_path / "manifest.json").read_text())["status"] == "finished"


def test_a_collection_made_with_other_scenario_values_is_not_finished(reference, monkeypatch):
    """A new fit of `lab` changes its constants: collections cached before it are not reused."""
    from collectors.runner import CollectRequest, finished
    from macrostate_mj.chain import scenarios

    req = CollectRequest("lab", 3, 0.75, 5, reference, "passive", split="60/10/30",
                         episode_minutes=0.25)          # the name resolved here, once
    assert finished(req)
    refit = scenarios.SCENARIOS["lab"].with_overrides(k_f=9.0)
    monkeypatch.setitem(scenarios.SCENARIOS, "lab", refit)
    assert finished(req)                                # the request holds what it resolved
    assert not finished(replace(req, scenario="lab"))   # a new request gets the new fit


def _episodes(out):
    """The finished episodes' logs in a collection's task cache (not one still being written:
    `TaskCache.put` writes into a hidden `.part` folder, which pathlib's glob also matches)."""
    return sorted(p for p in (out / "cache" / "collect-episode").glob("*/episode.parquet")
                  if not p.parent.name.startswith("."))


def test_the_srs_phases_follow_collect_s_progress_callback():
    """`collect` reports (episodes, sim minutes, of them resumed); each SRS phase's reporter
    takes the same three (the CLI's `collect --policy srs` drives a bar with them)."""
    from collectors.srs_collection import _reporter

    seen = []
    _reporter(lambda *args: seen.append(args), "RO phase", 4)(2, 1.0, 0.5)
    assert seen == [("RO phase", 2, 4)]
