"""ThymioLoc CSV: exact round trips (real and synthetic), validation errors, chain statistics."""

from __future__ import annotations

import json

import numpy as np
import pytest
from clitools import cli_inprocess as _cli

from macrostate_mj.core.errors import UserError
from macrostate_mj.formats.instances import to_thymioloc_pixels
from macrostate_mj.formats.thymioloc import (
    chain_stats,
    format_csv,
    from_world,
    header,
    read_csv,
    to_world,
    write_csv,
)

REAL = ["Train.csv", "Val.csv"]


@pytest.mark.parametrize("name", REAL)
def test_real_files_read_unchanged_and_round_trip_byte_identical(reference_data, tmp_path, name):
    src = reference_data / "ReTLo" / "Datasets" / "3Robots" / name
    data = read_csv(src)
    assert data.poses.shape[1:] == (26, 3, 3) and data.robots == ["H", "F1", "T"]
    out = write_csv(tmp_path / name, data.poses)
    assert out.read_bytes() == src.read_bytes()


@pytest.mark.parametrize("name", REAL)
def test_real_headings_lie_in_minus_180_exclusive_to_180(reference_data, name):
    o = read_csv(reference_data / "ReTLo" / "Datasets" / "3Robots" / name).poses[..., 2]
    assert o.min() > -180 and o.max() <= 180
    if name == "Train.csv":
        assert np.sum(o == 180) == 104      # the published file's count


def test_headings_are_written_in_the_real_convention(tmp_path):
    """A heading a hair past -180 rounds to -180, which the real files never hold: it is 180."""
    world = np.zeros((1, 26, 3, 3))
    world[..., 2] = np.radians([-179.7, 179.7, -180.0])
    px = to_thymioloc_pixels(world, (2.5, 1.9), 3.0)
    o = read_csv(write_csv(tmp_path / "o.csv", px)).poses[..., 2]
    assert np.all(o == 180)


def test_real_train_statistics_match_the_published_calibration(reference_data):
    data = read_csv(reference_data / "ReTLo" / "Datasets" / "3Robots" / "Train.csv")
    s = chain_stats(data.poses, 3.0)
    assert s.spacing_cm[0] == pytest.approx(31.3, abs=0.05)
    assert s.spacing_cm[1] == pytest.approx(3.0, abs=0.05)
    assert [round(s.speed_cm_s[r], 1) for r in ("H", "F1", "T")] == [7.0, 5.7, 4.7]
    assert all(11 <= v <= 15 for v in s.turn_deg_s.values())


def test_synthetic_round_trip_any_chain_length(tmp_path):
    rng = np.random.default_rng(1)
    poses = rng.integers(-200, 800, size=(4, 7, 5, 3))
    poses[..., 2] = rng.integers(-179, 181, size=(4, 7, 5))     # o in (-180, 180]
    path = write_csv(tmp_path / "five.csv", poses)
    back = read_csv(path)
    assert np.array_equal(back.poses, poses)
    assert back.robots == ["H", "F1", "F2", "F3", "T"]
    assert path.read_text().splitlines()[0].split(",")[:4] == ["0_H_x", "0_H_y", "0_H_o", "0_F1_x"]
    assert header(5, 7)[-1] == "6_T_o" and len(header(5, 7)) == 7 * 5 * 3


def test_world_conversion_is_right_handed_and_invertible():
    px = np.array([[[[30.0, 60.0, 90.0]]]])  # heading 90° = up on screen = y decreasing
    w = to_world(px, 3.0)
    assert w[0, 0, 0].tolist() == pytest.approx([10.0, -20.0, np.pi / 2])
    assert np.allclose(from_world(w, 3.0), px)


def _straight_chain(n_robots: int, v_px: float, spacing_px: float, n_steps: int = 6):
    """Robots on a horizontal line heading right (o = 0), moving v_px per step."""
    t = np.arange(n_steps)[:, None]
    x = 500 - spacing_px * np.arange(n_robots)[None, :] + v_px * t
    poses = np.stack([x, np.full_like(x, 200.0), np.zeros_like(x)], -1)
    return poses[None]


def test_chain_stats_on_a_known_chain():
    s = chain_stats(_straight_chain(4, v_px=6.0, spacing_px=90.0), px_per_cm=3.0)
    assert s.spacing_cm[:2] == pytest.approx((30.0, 0.0))
    assert s.speed_cm_s == pytest.approx({"H": 4.0, "F1": 4.0, "F2": 4.0, "T": 4.0})
    assert s.turn_deg_s == pytest.approx({"H": 0.0, "F1": 0.0, "F2": 0.0, "T": 0.0})
    spin = _straight_chain(3, 0.0, 90.0, n_steps=5)
    spin[0, :, :, 2] = (np.arange(5)[:, None] * 100 + 170) % 360 - 180  # 100° per step, wrapping
    assert chain_stats(spin, 3.0).turn_deg_s["H"] == pytest.approx(200.0)


def test_stats_command_prints_files_side_by_side(tmp_path, capsys):
    a = write_csv(tmp_path / "three.csv", _straight_chain(3, 6.0, 90.0))
    b = write_csv(tmp_path / "five.csv", _straight_chain(5, 3.0, 93.0))
    code, out, _ = _cli(capsys, "stats", str(a), str(b))
    assert code == 0
    assert "three.csv" in out and "five.csv" in out and "30.0 ± 0.0" in out and "31.0 ± 0.0" in out
    assert "speed F3" in out
    code, out, _ = _cli(capsys, "stats", str(a), str(b), "--json")
    rows = [json.loads(line) for line in out.splitlines()]
    assert code == 0 and [r["file"] for r in rows] == [str(a), str(b)]
    assert rows[0]["spacing_cm"][0] == pytest.approx(30.0) and "F3" in rows[1]["speed_cm_s"]


GOOD = ",".join(header(3, 2)) + "\n" + ",".join(["1"] * 18) + "\n"
BAD = {
    "not ThymioLoc header": ("a,b,c\n1,2,3\n", "line 1 is not a ThymioLoc header"),
    "columns out of order": (",".join(header(3, 2)[::-1]) + "\n" + ",".join(["1"] * 18) + "\n",
                             "line 1 is not a ThymioLoc header"),
    "wrong field count": (GOOD + ",".join(["1"] * 17) + "\n", "line 3 has 17 fields"),
    "non-number": (GOOD + ",".join(["1"] * 17 + ["x"]) + "\n", "line 3, column 1_T_o: 'x'"),
    "float": (GOOD + ",".join(["1.5"] + ["1"] * 17) + "\n", "line 3, column 0_H_x"),
    "empty": ("", "empty file"),
    "header only": (",".join(header(3, 2)) + "\n", "no instances"),
}


@pytest.mark.parametrize("case", list(BAD))
def test_malformed_file_exits_2_with_one_line_naming_file_and_row(tmp_path, capsys, case):
    text, expected = BAD[case]
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(UserError, match="bad.csv"):
        read_csv(path)
    code, out, err = _cli(capsys, "stats", str(path))
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and expected in err and "Traceback" not in err


def test_missing_file_and_bad_scale_exit_2(tmp_path, capsys):
    code, _, err = _cli(capsys, "stats", str(tmp_path / "nope.csv"))
    assert code == 2 and "nope.csv does not exist" in err
    good = tmp_path / "good.csv"
    good.write_text(GOOD)
    code, _, err = _cli(capsys, "stats", str(good), "--px-per-cm", "0")
    assert code == 2 and "--px-per-cm" in err


def test_format_rounds_and_refuses_wrong_shapes():
    assert format_csv(np.full((1, 1, 2, 3), 2.6)).splitlines()[1] == "3,3,3,3,3,3"
    with pytest.raises(UserError):
        format_csv(np.zeros((2, 3)))
