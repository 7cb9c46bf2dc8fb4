"""Sim-to-real as a user runs it: pre-train, then fine-tune (`--init`) or train on both at once
(`--mix`), on synthetic stand-ins for "sim" and "real" chains of different dynamics."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch
from clitools import cli_inprocess as _cli

from estimators.retlo.api import fit
from estimators.retlo.files import world_to_pixels
from estimators.retlo.models import ModelConfig
from estimators.retlo.synthetic import synthetic_chains
from estimators.retlo.train import ENCODER, TrainConfig, load_checkpoint, train
from macrostate_mj.core.errors import UserError
from macrostate_mj.formats.thymioloc import write_csv

SMALL = ModelConfig(kind="fc", k=16, d=16)
SIM = synthetic_chains(30, 3, 1, head_speed=0.05)      # "sim": a slower Head than "real"
REAL = synthetic_chains(10, 3, 2)
VAL = synthetic_chains(8, 3, 3)


def test_fine_tuning_starts_from_the_model_and_can_keep_its_encoders():
    pre, _ = train([SIM], VAL, TrainConfig(epochs=2, model=SMALL), progress=False)
    tuned, info = fit([REAL], VAL, TrainConfig(epochs=2, lr=5e-4, model=SMALL, frozen=ENCODER),
                      init=pre)
    for name, p in tuned.state_dict().items():
        same = torch.equal(p, pre.state_dict()[name])
        assert same == name.startswith(ENCODER) or name == "pos_scale", name
    assert float(tuned.pos_scale) == float(pre.pos_scale)     # the pre-trained units
    assert info["epochs_run"] == 2
    other = ModelConfig(kind="lstm", k=16, m=16, d=16)
    with pytest.raises(UserError, match="initial model is a fc model"):
        fit([REAL], VAL, TrainConfig(epochs=1, model=other), init=pre)


def test_a_mix_weighs_each_group_by_its_share_of_the_loss():
    """The same data mixed at two weights trains two different models, and an unweighted run
    is unchanged by the feature (bit for bit the plain training)."""
    cfg = TrainConfig(epochs=2, model=SMALL)
    plain, _ = fit([REAL], VAL, cfg)
    again, _ = train([REAL], VAL, cfg, progress=False)
    assert all(torch.equal(a, b) for a, b in zip(plain.state_dict().values(),
                                                 again.state_dict().values(), strict=True))
    low, _ = fit([REAL], VAL, cfg, mix=[SIM], mix_weight=0.1)
    high, _ = fit([REAL], VAL, cfg, mix=[SIM], mix_weight=0.9)
    assert not torch.equal(low.state_dict()["g_p.weight"], high.state_dict()["g_p.weight"])
    for bad in (0.0, 1.0, float("nan")):
        with pytest.raises(UserError, match="mix_weight"):
            fit([REAL], VAL, cfg, mix=[SIM], mix_weight=bad)


def test_train_retlo_init_and_mix_from_the_command_line(tmp_path, capsys):
    files = {name: write_csv(tmp_path / f"{name}.csv", world_to_pixels(w, 3.0))
             for name, w in (("sim", SIM), ("real", REAL), ("val", VAL))}
    base = ["train", "retlo", "--model", "fc", "--val", str(files["val"]), "--epochs", "2"]
    code, _, err = _cli(capsys, *base, "--train", str(files["sim"]), "--out",
                        str(tmp_path / "sim.pt"))
    assert code == 0, err
    code, out, err = _cli(capsys, *base, "--train", str(files["real"]), "--init",
                          str(tmp_path / "sim.pt"), "--lr", "5e-4", "--freeze-encoder",
                          "--out", str(tmp_path / "tuned.pt"))
    assert code == 0, err
    _, ckpt = load_checkpoint(tmp_path / "tuned.pt")
    assert ckpt["train_config"]["lr"] == 5e-4 and ckpt["train_config"]["frozen"]
    manifest = json.loads((tmp_path / "tuned.pt.manifest.json").read_text())
    assert manifest["init"].endswith("sim.pt")
    code, _, err = _cli(capsys, *base, "--train", str(files["real"]), "--mix",
                        str(files["sim"]), "--mix-weight", "0.3", "--out",
                        str(tmp_path / "mixed.pt"))
    assert code == 0, err
    assert json.loads((tmp_path / "mixed.pt.manifest.json").read_text())["mix_weight"] == 0.3
    for args, words in (
            (["--init", str(tmp_path / "sim.pt"), "--unidirectional"], "different model"),
            (["--model", "lstm", "--init", str(tmp_path / "sim.pt")], "kind: it has 'fc'"),
            (["--freeze-encoder"], "pass --init"),
            (["--mix", str(files["sim"]), "--mix-weight", "1"], "--mix-weight"),
            (["--mix-weight", "1.5"], "--mix-weight")):
        target = tmp_path / "bad.pt"
        code, _, err = _cli(capsys, *base, "--train", str(files["real"]), *args, "--out",
                            str(target))
        assert code == 2 and words in err and len(err.strip().splitlines()) == 1, (args, err)
        assert not target.exists() and not (tmp_path / "bad.pt.manifest.json").exists()
    assert np.isfinite(ckpt["train_info"]["best_val_cm"])
