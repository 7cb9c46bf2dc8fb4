"""Loader of the OpticalFlows_HsAnts layout: real data, a synthetic layout, bins, bad input."""

import json
from pathlib import Path

import numpy as np
import pytest
from builders import make_layout

from macrostate_mj.core.errors import UserError
from macrostate_mj.formats.hsants import BIN_NAMES, open_dataset


def test_real_layout(reference_data):
    d = open_dataset(reference_data / "OpticalFlows_HsAnts")
    assert (len(d.stable_ids), len(d.unstable_ids), d.subframes) == (1333, 48, 4)
    train, test = d.split(1)
    assert (len(train), len(test)) == (1067, 266)
    assert not set(train) & set(test) and set(train) | set(test) == set(d.stable_ids)
    x = d.load("Stable", test[:5], 2)
    assert x.shape == (5, 4, 64, 64) and x.dtype == np.float32
    assert -1.0 <= x.min() and x.max() <= 1.0 and abs(np.median(x)) < 0.02  # 128 = still
    bins = d.time_bin(d.unstable_ids)
    assert all(bins.count(b) == 8 for b in BIN_NAMES)  # the shipped smoke set: 8 per bin


def test_bins_follow_ids_and_bins_json(tmp_path):
    d = open_dataset(make_layout(tmp_path / "a", stable=1333 // 100, unstable=(20, 30)))
    # n_stable = 13, so id 13 is the first unstable position: D+1 until 13 + 666
    assert d.time_bin([13, 13 + 665, 13 + 666, 13 + 4000, 13 + 11983, 13 + 11984]) == [
        "D+1", "D+1", "D+2", "D+7-10", "D+15-18", None]
    root = make_layout(tmp_path / "b", stable=10, unstable=(10, 11, 12))
    (root / "bins.json").write_text(json.dumps({"early": [10, 12], "late": [12, 13]}))
    assert open_dataset(root).time_bin([10, 11, 12]) == ["early", "early", "late"]


def test_synthetic_layout_values(tmp_path):
    d = open_dataset(make_layout(tmp_path / "ds"))
    assert d.subframes == 2 and d.unstable_ids == (1333, 1999, 5000)
    xu = d.load("Unstable", d.unstable_ids, 2)
    assert xu.shape == (3, 4, 64, 64)
    assert np.median(xu) * 20 == pytest.approx(4.0, abs=0.2)  # back to px: ±20 px = ±1


def test_bad_datasets(tmp_path):
    root = make_layout(tmp_path / "ds")
    d = open_dataset(root)
    with pytest.raises(UserError, match="m 3 needs 3 sub-frames"):
        d.load("Stable", [0], 3)
    bad = root / "Stable" / "flow_y_00003-1.jpg"
    bad.write_bytes(bad.read_bytes()[:200])  # truncated JPEG
    with pytest.raises(UserError, match="corrupt JPEG .*flow_y_00003-1.jpg"):
        d.load("Stable", [2, 3], 2)
    (root / "split2" / "test.csv").unlink()
    with pytest.raises(UserError, match="split2/test.csv"):
        d.split(2)
    with pytest.raises(UserError, match="no Unstable/"):
        open_dataset(_drop(tmp_path / "y"))


def _drop(root: Path) -> Path:
    make_layout(root)
    for f in (root / "Unstable").iterdir():
        f.unlink()
    (root / "Unstable").rmdir()
    return root
