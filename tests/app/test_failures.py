"""A run whose physics fails: one line, exit 1, and what was done before the failure kept."""

import json
import re

import pyarrow.parquet as pq
import pytest
from clitools import cli_inprocess

from macrostate_mj.chain.health import Fault, PhysicsFault, PhysicsMonitor

FAULT_AT = 3.0


class TipsAt(PhysicsMonitor):
    """A monitor that sees the Head tip at FAULT_AT s: a physics failure on demand."""

    def check(self, data, t=None):
        t = float(data.time) if t is None else t
        fault = super().check(data, t)
        return fault or (PhysicsFault(Fault.TIP, "H", t, 31.0) if t >= FAULT_AT else None)


def strict_after(monkeypatch, healthy: int) -> None:
    """The first `healthy` monitors built are real, the later ones `TipsAt`."""
    built = []

    def monitor(world):
        built.append(world)
        return (PhysicsMonitor if len(built) <= healthy else TipsAt)(world)

    monkeypatch.setattr("macrostate_mj.chain.sim.PhysicsMonitor", monitor)


def one_line(err: str) -> str:
    """The one message line, beside the progress log lines printed off a terminal."""
    lines = [ln for ln in err.strip().splitlines() if not re.match(r"\d\d:\d\d:\d\d ", ln)]
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


def test_simulate_keeps_poses_and_video_up_to_the_fault(monkeypatch, capsys, tmp_path):
    strict_after(monkeypatch, 0)
    out, video = tmp_path / "run", tmp_path / "run.mp4"
    code, _, err = cli_inprocess(capsys, "simulate", "--robots", "3", "--seconds",
                                 "30", "--seed", "4", "--out", str(out), "--video", str(video))
    line = one_line(err)
    assert code == 1
    for words in ("tipped", "seed 4", "reproduce: macrostate-mj simulate", "--seed 4"):
        assert words in line
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["status"] == "failed" and manifest["fault"]["fault"] == "TIP"
    t_fault = manifest["fault"]["time"]
    assert t_fault == pytest.approx(FAULT_AT) == manifest["simulated_seconds"]
    t = pq.read_table(out / "poses.parquet").column("t").to_numpy()
    assert len(t) > 0 and t.max() <= t_fault
    assert video.stat().st_size > 0


def test_collect_names_the_failed_episode_and_keeps_finished_shards(monkeypatch, capsys,
                                                                    tmp_path):
    args = ["collect", "--robots", "3", "--minutes", "0.5", "--episode-minutes", "0.25",
            "--seed", "3", "--out", str(tmp_path)]
    strict_after(monkeypatch, 1)
    code, _, err = cli_inprocess(capsys, *args)
    line = one_line(err)
    assert code == 1
    assert "episode 1 (seeds [3, 1, 0..2])" in line and "tipped 31 deg at t=3.000 s" in line
    assert len(list((tmp_path / "cache" / "collect-episode").glob("*/episode.parquet"))) == 1
    assert not (tmp_path / "instances.csv").exists()
    manifest = json.loads((tmp_path / "manifest.json").read_text())
    assert manifest["status"] == "failed" and "episode 1" in manifest["failure"]
    monkeypatch.undo()
    code, _, err = cli_inprocess(capsys, *args)   # the resumed run finishes it
    assert code == 0, err
    manifest = json.loads((tmp_path / "manifest.json").read_text())
    assert manifest["resumed_episodes"] == 1


def test_soak_prints_its_table_and_exits_1_on_a_fault(monkeypatch, capsys, tmp_path):
    base = ["soak", "--robots", "3", "--seeds", "2", "--seconds", "5"]
    code, out, err = cli_inprocess(capsys, *base, "--out", str(tmp_path))
    assert code == 0, err
    head, row = out.splitlines()[1:3]
    assert head.split()[:5] == ["runs", "tips", "NaNs", "escapes", "climbs"]
    assert row.split()[:5] == ["2", "0", "0", "0", "0"]
    report = json.loads((tmp_path / "soak.json").read_text())
    assert [r["seed"] for r in report["runs"]] == [0, 1]
    strict_after(monkeypatch, 0)
    code, out, err = cli_inprocess(capsys, *base, "--json")
    assert code == 1 and json.loads(out)["tips"] == 2
    assert "seed 0" in one_line(err)


def test_ctrl_c_in_simulate_leaves_only_its_record(monkeypatch, capsys, tmp_path):
    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr("macrostate_mj.chain.sim.ChainSim.run", interrupted)
    out = tmp_path / "run"
    code, _, err = cli_inprocess(capsys, "simulate", "--robots", "3", "--seconds", "5",
                                 "--out", str(out))
    assert code == 130 and err.strip() == "interrupted"
    assert [p.name for p in out.iterdir()] == ["manifest.json"]      # no half-written poses
    assert json.loads((out / "manifest.json").read_text())["status"] == "interrupted"
