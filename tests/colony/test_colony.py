"""Simulated ant colony: behaviour math, physics of a duel, determinism, and `ants simulate`."""

import csv
import json

import cv2
import numpy as np
import pytest
from clitools import cli_inprocess

import macrostate_mj  # noqa: F401  (sets MUJOCO_GL before mujoco loads)
from macrostate_mj.colony.colony_sim import (
    BEHAVIOURS,
    DUEL,
    HEAD_TIP,
    REST,
    Colony,
    ColonyConfig,
    aggression,
    parse_days,
    regime,
)
from macrostate_mj.core.errors import UserError


def test_aggression_peaks_after_removal_and_fades_by_day_10():
    days = np.array([-2, -1, *range(1, 19)])
    a = aggression(days)
    assert a[days < 0].max() == 0.0
    assert days[a.argmax()] in (1, 2, 3) and a.max() == 1.0
    after = a[days >= 3]
    assert np.all(np.diff(after) <= 0)  # only fades once the peak is over
    assert aggression(6) < 0.5 and aggression(10) < 0.1 and aggression(18) > 0  # a few still fight
    stable, peak = regime(0.0), regime(1.0)
    assert stable.duel_rate == stable.bite_rate == 0 and peak.duel_rate > 0
    assert peak.speed > stable.speed and peak.solo_p[1] > stable.solo_p[1]


def test_parse_days():
    assert parse_days("D-2..D+2") == [-2, -1, 1, 2]
    assert parse_days("D+5,D-1") == [-1, 5]
    for bad in ("D+3..D-1", "D0", "X5", "D+19", "", "D+1..", "D+a"):
        with pytest.raises(UserError):
            parse_days(bad)


def _force_duel(colony: Colony) -> None:
    """Ants 0 and 1 duel for the whole run; the others rest far from any interaction."""
    colony.beh[:] = REST
    colony.beh[:2], colony.partner[:2] = DUEL, [1, 0]
    colony.timer[:] = 1e9
    colony.cooldown[:] = 1e9


def test_duel_faces_ants_and_drums_antennae_fast():
    colony = Colony(ColonyConfig(n_ants=4, fps=60.0, warmup_s=0.0, seed=1))
    colony.reset(1)
    _force_duel(colony)
    ant_l, thorax = [], []
    for _ in range(150):  # 2.5 s; antennae sampled at 60 Hz
        colony.advance_frame()
        ant_l.append(colony.data.qpos[colony.qa].copy())
        thorax.append(colony.poses[0][:2].copy())
    pos, yaw = colony.poses
    u = (pos[1] - pos[0]) / np.linalg.norm(pos[1] - pos[0])
    head = np.stack([np.cos(yaw), np.sin(yaw)], 1)
    assert head[0] @ head[1] < -0.97  # facing each other ...
    assert head[0] @ u > 0.97 and head[1] @ -u > 0.97  # ... along the line between them
    assert np.linalg.norm(pos[1] - pos[0]) < 2 * HEAD_TIP + 0.006  # head tips a few mm apart
    tips = colony.data.site_xpos[colony.sites[:2, 0]]
    assert np.linalg.norm(tips[0] - tips[1]) < 0.006
    q = np.array(ant_l)[60:]  # last 1.5 s, after the approach
    crossings = (np.diff(np.sign(q - q.mean(axis=0)), axis=0) != 0).sum(axis=0) / 2 / 1.5
    swing = q.max(axis=0) - q.min(axis=0)
    assert crossings[0] > 5 and crossings[1] > 5  # duelers drum at ~7 Hz
    assert swing[0] > 0.5 and swing[1] > 0.5  # over half a radian peak to peak
    assert crossings[2] < 2 and swing[2] < 0.4  # a resting ant barely moves its antennae
    assert np.isfinite(colony.data.qpos).all() and np.abs(pos).max() < 0.075
    p = np.array(thorax)[60:]  # the pair jerks back and forth together, spacing held
    moved = np.linalg.norm(p[30:] - p[:-30], axis=2).max(axis=0)  # over 0.5 s, the flow gap
    assert (moved > 0.007).all() and (moved < 0.011).all()
    assert np.ptp(np.linalg.norm(p[:, 0] - p[:, 1], axis=1)) < 0.001


def _trace(seed: int, frames: int = 20) -> tuple[np.ndarray, list]:
    colony = Colony(ColonyConfig(n_ants=12, fps=10.0, warmup_s=0.2, seed=seed))
    colony.reset(2)
    first = colony.data.qpos.copy()
    colony.reset(2)  # a second reset of the same day must start from the same full state
    assert np.array_equal(first, colony.data.qpos)
    poses, events = [], []
    for _ in range(frames):
        colony.advance_frame()
        poses.append(colony.data.qpos.copy())
        events.append([BEHAVIOURS[b] for b in colony.beh])
    return np.array(poses), events


def test_same_seed_same_trajectory_other_seed_differs():
    a, ea = _trace(3)
    b, eb = _trace(3)
    c, _ = _trace(4)
    assert np.array_equal(a, b) and ea == eb
    assert not np.allclose(a, c)


def _cli(capsys, *args: str) -> tuple[int, str, str]:
    return cli_inprocess(capsys, "ants", "simulate", *args)


SMALL = ["--ants", "12", "--days", "D-1,D+1", "--seconds-per-day", "3", "--size", "64",
         "--fps", "10", "--every", "1", "--m", "2", "--seed", "0"]


def test_simulate_end_to_end_writes_flows_labels_and_boxes(tmp_path, capsys):
    out = tmp_path / "colony"
    code, _, err = _cli(capsys, "--out", str(out), *SMALL, "--save-video", "--save-frames")
    assert code == 0, err
    flows = out / "flows"
    stable = sorted(p.name for p in (flows / "Stable").glob("flow_x_*-0.jpg"))
    unstable = sorted(p.name for p in (flows / "Unstable").glob("flow_x_*-0.jpg"))
    ids_s = [int(n[7:12]) for n in stable]
    ids_u = [int(n[7:12]) for n in unstable]
    assert ids_s and ids_u and max(ids_s) < min(ids_u)  # stable first, global temporal order
    assert ids_s + ids_u == list(range(len(ids_s) + len(ids_u)))
    img = cv2.imread(str(flows / "Unstable" / unstable[0]), cv2.IMREAD_GRAYSCALE)
    assert img.shape == (64, 64)
    assert (flows / "Unstable" / f"img_{ids_u[0]:05d}-1.jpg").is_file()
    for k in (1, 2, 3):
        train = (flows / f"split{k}" / "train.csv").read_text().split()
        test = (flows / f"split{k}" / "test.csv").read_text().split()
        assert sorted(train + test) == [f"Stable/{i:05d}" for i in ids_s] and test
    labels = list(csv.DictReader(open(out / "labels.csv")))
    assert {r["label"] for r in labels if r["day"] == "D-1"} == {"Stable"}
    assert {r["label"] for r in labels if r["day"] == "D+1"} == {"Unstable"}
    boxes = list(csv.DictReader(open(flows / "boxes.csv")))
    assert boxes, "seed 0 has a duel or bite on D+1"
    for r in boxes:
        x, y, w, h = (float(r[c]) for c in "xywh")
        assert int(r["sample_id"]) in ids_u and 0 <= x and x + w <= 64 and 0 < w and 0 < h
    assert json.loads((flows / "bins.json").read_text()) == {"D+1": [min(ids_u), max(ids_u) + 1]}
    frame_boxes = list(csv.DictReader(open(out / "boxes.csv")))
    assert {r["kind"] for r in frame_boxes} <= {"duel", "bite"} and frame_boxes
    assert len(list((out / "frames" / "D+1").glob("*.jpg"))) == 30
    assert (out / "video" / "D-1.mp4").stat().st_size > 0
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["samples"] == {"Stable": len(ids_s), "Unstable": len(ids_u)}
    assert not list(out.glob(".colony-stage-*"))


def test_simulate_same_seed_same_products(tmp_path, capsys):
    for name in ("a", "b"):
        code, _, err = _cli(capsys, "--out", str(tmp_path / name), *SMALL,
                            "--days", "D+1")
        assert code == 0, err
    for rel in ("labels.csv", "boxes.csv", "flows/boxes.csv", "flows/Unstable/flow_x_00001-1.jpg"):
        assert (tmp_path / "a" / rel).read_bytes() == (tmp_path / "b" / rel).read_bytes()


@pytest.mark.parametrize("args", [
    ["--days", "D+3..D-1"],
    ["--days", "D0"],
    ["--seconds-per-day", "0"],
    ["--seconds-per-day", "-4"],
    ["--size", "8"],
    ["--size", "100"],
    ["--method", "nope"],
])
def test_bad_input_exits_2_with_one_line_and_writes_nothing(tmp_path, capsys, args):
    out = tmp_path / "run"
    code, _, err = _cli(capsys, "--out", str(out), *SMALL, *args)
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("error: ") and "Traceback" not in err
    assert not out.exists()


def test_existing_output_needs_overwrite(tmp_path, capsys):
    out = tmp_path / "run"
    (out / "flows").mkdir(parents=True)
    code, _, err = _cli(capsys, "--out", str(out), *SMALL)
    assert code == 2 and "--overwrite" in err and err.count("\n") == 1
    assert [p.name for p in out.iterdir()] == ["flows"] and not any((out / "flows").iterdir())
