"""`soak --out` keeps every finished seed: an interrupted soak resumes where it stopped."""

import json

from clitools import cli_inprocess

import macrostate_mj.chain.soak as soak_module


def test_an_interrupted_soak_resumes_from_its_finished_seeds(monkeypatch, capsys, tmp_path):
    args = ["soak", "--robots", "3", "--seeds", "3", "--seconds", "4", "--out", str(tmp_path)]
    assert cli_inprocess(capsys, *args)[0] == 0
    first = json.loads((tmp_path / "soak.json").read_text())["runs"]
    (tmp_path / "soak.json").unlink()                 # as if killed before the end ...
    (tmp_path / "manifest.json").unlink()
    (tmp_path / "runs" / "seed_000001.json").unlink()  # ... and before seed 1 finished
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
    code, _, err = cli_inprocess(capsys, "soak", "--robots", "4", "--seeds", "3",
                                 "--seconds", "4", "--out", str(tmp_path))
    assert code == 2 and "runs of another soak" in err
