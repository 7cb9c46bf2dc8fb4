"""`soak --out` keeps every finished seed: an interrupted soak resumes where it stopped."""

import json
import shutil

from clitools import cli_inprocess

import macrostate_mj.chain.physics_soak as soak_module


def test_an_interrupted_soak_resumes_from_its_finished_seeds(monkeypatch, capsys, tmp_path):
    args = ["soak", "--robots", "3", "--seeds", "3", "--seconds", "4", "--out", str(tmp_path)]
    assert cli_inprocess(capsys, *args)[0] == 0
    first = json.loads((tmp_path / "soak.json").read_text())["runs"]
    (tmp_path / "soak.json").unlink()                 # as if killed before the end ...
    (tmp_path / "manifest.json").unlink()
    for run in (tmp_path / "cache" / "soak-run").glob("*/run.json"):
        if json.loads(run.read_text())["seed"] == 1:  # ... and before seed 1 finished
            shutil.rmtree(run.parent)
    ran = []
    real = soak_module.soak_one
    monkeypatch.setattr(soak_module, "soak_one", lambda task: ran.append(task.seed) or real(task))
    assert cli_inprocess(capsys, *args)[0] == 0
    assert ran == [1]
    again = json.loads((tmp_path / "soak.json").read_text())["runs"]
    drop = ("wall_s",)
    assert [{k: v for k, v in r.items() if k not in drop} for r in again] == \
        [{k: v for k, v in r.items() if k not in drop} for r in first]
    for name in ("soak.json", "manifest.json"):
        (tmp_path / name).unlink()
    ran.clear()          # another soak in the same folder: its own keys, nothing mixed
    code, _, err = cli_inprocess(capsys, "soak", "--robots", "4", "--seeds", "3",
                                 "--seconds", "4", "--out", str(tmp_path))
    assert code == 0, err and ran == [0, 1, 2]
    assert json.loads((tmp_path / "soak.json").read_text())["summary"]["robots"] == 4
