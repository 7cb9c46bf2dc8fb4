"""ReTLo: frames, modular inference on chains with known answers, training, checkpoints, CLI."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
import torch
from clitools import cli_inprocess as _cli

from estimators.precision import lstm_runs
from estimators.retlo.chain import SplitChain, predict_chain, tracks_from_world, window
from estimators.retlo.files import pixels_to_world, read_world, world_to_pixels
from estimators.retlo.frames import FrameEstimate, history_features
from estimators.retlo.heuristic import Heuristic2X
from estimators.retlo.models import ModelConfig, RetloNet, TorchPredictor, net_features
from estimators.retlo.report import evaluate_chain
from estimators.retlo.synthetic import synthetic_chains
from estimators.retlo.train import (
    FORMAT,
    TrainConfig,
    load_checkpoint,
    save_checkpoint,
    train,
)
from macrostate_mj.app.experiments.retlo import CV_TEST
from macrostate_mj.core.errors import UserError
from macrostate_mj.core.frames import from_frame, to_frame
from macrostate_mj.formats.thymioloc import write_csv

TINY = dict(k=16, m=16, d=16)


def _rigid(n_robots: int, shape: str, n_inst: int = 2, n_steps: int = 26) -> np.ndarray:
    """A rigid chain (metres) translating at constant velocity: a straight line (along its
    motion) or a zigzag; headings constant. The answer is known at every step."""
    v = np.array([0.04, 0.03])
    offsets = np.stack([-0.31 * np.arange(n_robots) * 0.8, -0.31 * np.arange(n_robots) * 0.6], -1)
    if shape == "zigzag":
        offsets[1::2] += np.array([-0.12, 0.16])
    t = np.arange(n_steps)[:, None, None]
    xy = np.array([1.0, 0.5]) + offsets[None] + v * t
    theta = np.full((n_steps, n_robots, 1), np.arctan2(3.0, 4.0))
    one = np.concatenate([xy, theta], -1)
    world = np.repeat(one[None], n_inst, axis=0)
    world[..., :2] += np.arange(n_inst)[:, None, None, None] * 0.07
    return world


class ConstantVelocity:
    """A chain `Module` that extrapolates the Head from the last two history steps: exact for a
    rigid translating chain only if fed-back estimates and frame changes are handled right."""

    history, rotate = 10, True

    def features(self, win):
        return history_features(win, cos_sin=False, mark_estimates=False)

    def estimate(self, x):
        _, hist = x
        return FrameEstimate(2 * hist[:, -1, 0:2] - hist[:, -2, 0:2], head_theta=hist[:, -1, 2],
                             fol_theta=hist[:, -1, 5])


def test_frame_round_trip():
    rng = np.random.default_rng(0)
    pts, origin, alpha = rng.normal(size=(5, 2)), rng.normal(size=(5, 2)), rng.normal(size=5)
    assert np.allclose(from_frame(to_frame(pts, origin, alpha), origin, alpha), pts)


@pytest.mark.parametrize("n_robots", [3, 4, 5, 7])
def test_heuristic_is_exact_on_a_straight_rigid_chain_of_any_length(n_robots):
    world = _rigid(n_robots, "straight")
    report = evaluate_chain(Heuristic2X(), world)
    assert report["mean_error_cm"] < 1e-9
    names = {3: ["H"], 4: ["F2", "H"], 5: ["F2", "F3", "H"], 7: ["F2", "F3", "F4", "F5", "H"]}
    assert list(report["per_robot_cm"]) == names[n_robots]
    # module k reaches step S-2-k: the linear delay of §2.5.1.2
    assert sum(v is not None for v in report["per_robot_step_cm"]["H"]) == 26 - 10 - (n_robots - 2)


@pytest.mark.parametrize("rotate", [True, False])
@pytest.mark.parametrize("n_robots", [3, 5, 6])
def test_fed_back_estimates_and_frames_are_exact_on_a_translating_zigzag(n_robots, rotate):
    world = _rigid(n_robots, "zigzag")
    assert evaluate_chain(Heuristic2X(), world)["mean_error_cm"] > 5  # shape matters here
    pred = ConstantVelocity()
    pred.rotate = rotate
    est = predict_chain(pred, world)
    seen = ~np.isnan(est[..., 0])
    assert seen.sum() > 0 and np.allclose(est[seen], world[seen], atol=1e-8)
    # truth after τ is never read: scrambling it changes nothing
    scrambled = world.copy()
    scrambled[:, 10:, :-2] += 10.0  # every robot but the Tail and its neighbour
    scrambled[:, 10:, -2, 2] += 1.0  # the neighbour's heading is not observed either
    assert np.allclose(predict_chain(pred, scrambled)[seen], est[seen])


def test_chain_refuses_short_chains_and_short_instances():
    with pytest.raises(UserError, match="at least 3"):
        predict_chain(Heuristic2X(), _rigid(2, "straight"))
    with pytest.raises(UserError, match="steps"):
        predict_chain(Heuristic2X(), _rigid(3, "straight", n_steps=11))
    with pytest.raises(UserError, match="no chains"):
        predict_chain(Heuristic2X(), _rigid(3, "straight")[:0])
    with pytest.raises(UserError, match=r"\(instances, steps, robots, 3\)"):
        predict_chain(Heuristic2X(), _rigid(3, "straight")[0])


def test_training_refuses_bad_settings_and_chains_that_are_not_finite():
    for settings, words in ((dict(epochs=0), "epochs"), (dict(batch=2.5), "batch"),
                            (dict(patience=True), "patience"), (dict(threads=0), "threads"),
                            (dict(lr=float("nan")), "lr"), (dict(lr=0.0), "lr"),
                            (dict(angle_weight=-1.0), "angle_weight")):
        with pytest.raises(UserError, match=words) as caught:
            TrainConfig(**settings)
        assert caught.value.param == words
    good, holed = synthetic_chains(4, 3, seed=1), synthetic_chains(4, 3, seed=1)
    holed[2, 5, 1, 0] = np.nan
    cfg = TrainConfig(epochs=1)
    with pytest.raises(UserError, match="training file 1 holds 1 NaN .* 1 instances"):
        train([holed], good, cfg, progress=False)
    with pytest.raises(UserError, match="validation file holds 1 NaN"):
        train([good], holed, cfg, progress=False)


def _fit(kind: str, seed: int = 0, epochs: int = 10):
    cfg = TrainConfig(epochs=epochs, patience=10, seed=seed, batch=64, lr=3e-3,
                      model=ModelConfig(kind=kind, **TINY))
    return train([synthetic_chains(40, 3, seed=1)], synthetic_chains(12, 3, seed=2), cfg,
                 progress=False), cfg


@pytest.mark.parametrize("kind", ["fc", "lstm"])
def test_training_lowers_validation_error(kind):
    val = synthetic_chains(12, 3, seed=2)
    torch.manual_seed(0)
    untrained = evaluate_chain(TorchPredictor(RetloNet(ModelConfig(kind=kind, **TINY), 31.0)),
                               val)["mean_error_cm"]
    (net, info), _ = _fit(kind)
    trained = evaluate_chain(TorchPredictor(net), val)["mean_error_cm"]
    assert trained == pytest.approx(info["best_val_cm"])
    assert trained < 0.5 * untrained
    assert info["curve"][-1]["train_loss"] < info["curve"][0]["train_loss"]


def _bf16_repeats_keeps_float32_weights_and_learns(kind: str) -> None:
    val = synthetic_chains(12, 3, seed=2)
    cfg = TrainConfig(epochs=4, seed=0, batch=64, lr=3e-3, precision="bf16",
                      model=ModelConfig(kind=kind, **TINY))
    runs = [train([synthetic_chains(40, 3, seed=1)], val, c, progress=False)
            for c in (cfg, cfg, replace(cfg, precision="fp32"))]
    (one, info), (two, _), (fp32, _) = runs
    assert all(p.dtype == torch.float32 for p in one.parameters())
    state, again, full = one.state_dict(), two.state_dict(), fp32.state_dict()
    assert all(torch.equal(state[k], again[k]) for k in state)
    assert not all(torch.equal(state[k], full[k]) for k in state)
    assert info["curve"][-1]["train_loss"] < info["curve"][0]["train_loss"]


def test_bf16_training_repeats_keeps_float32_weights_and_learns():
    """FC's matrix products run in bfloat16 on any CPU (emulated where it lacks the unit)."""
    _bf16_repeats_keeps_float32_weights_and_learns("fc")
    with pytest.raises(UserError, match="unknown precision 'half'"):
        TrainConfig(precision="half")


def test_bf16_lstm_trains_where_the_cpu_can_and_is_refused_in_one_line_where_not():
    """oneDNN has a bfloat16 LSTM on AVX512 CPUs only: elsewhere the config is refused before
    any work, naming the fix, instead of a RuntimeError from deep inside the first batch."""
    if lstm_runs("bfloat16", "cpu"):
        _bf16_repeats_keeps_float32_weights_and_learns("lstm")
    else:
        with pytest.raises(UserError, match="cannot run an LSTM in bf16.*--precision fp32"):
            TrainConfig(precision="bf16", model=ModelConfig(kind="lstm", **TINY))
    TrainConfig(precision="bf16", model=ModelConfig(kind="fc", **TINY))   # no LSTM: accepted


def test_checkpoint_round_trip_is_exact_and_versioned(tmp_path):
    (net, info), cfg = _fit("lstm", epochs=1)
    path = save_checkpoint(tmp_path / "m.pt", net, 3.0, cfg, info)
    loaded, ckpt = load_checkpoint(path)
    assert ckpt["kind"] == "lstm" and ckpt["px_per_cm"] == 3.0 and ckpt["format"] == FORMAT
    world = synthetic_chains(5, 5, seed=3)
    assert np.array_equal(predict_chain(TorchPredictor(net), world),
                          predict_chain(TorchPredictor(loaded), world), equal_nan=True)
    ckpt["version"] = 99
    torch.save(ckpt, tmp_path / "future.pt")
    with pytest.raises(UserError, match="version 99"):
        load_checkpoint(tmp_path / "future.pt")


def test_same_seed_same_checkpoint_bytes(tmp_path):
    for name in ("a", "b"):
        (net, info), cfg = _fit("fc", epochs=2)
        save_checkpoint(tmp_path / f"{name}.pt", net, 3.0, cfg, info)
    assert (tmp_path / "a.pt").read_bytes() == (tmp_path / "b.pt").read_bytes()


def test_train_and_evaluate_commands_on_any_chain_length(tmp_path, capsys):
    train_csv = write_csv(tmp_path / "train.csv", world_to_pixels(synthetic_chains(30, 3, 1), 3.0))
    val_csv = write_csv(tmp_path / "val.csv", world_to_pixels(synthetic_chains(8, 3, 2), 3.0))
    five = write_csv(tmp_path / "five.csv", world_to_pixels(synthetic_chains(6, 5, 3), 3.0))
    model = tmp_path / "fc.pt"
    code, out, err = _cli(capsys, "train", "retlo", "--model", "fc", "--train",
                          str(train_csv), "--val", str(val_csv), "--out", str(model),
                          "--seed", "0", "--epochs", "2")
    assert code == 0, err
    assert model.is_file() and (tmp_path / "fc.pt.manifest.json").is_file()
    for name in (str(model), "heuristic2x"):
        report_path = tmp_path / f"{name[-5:]}.json"
        code, out, err = _cli(capsys, "evaluate", "retlo", "--model", name,
                              "--data", str(five), "--out", str(report_path))
        assert code == 0, err
        assert "F3 (CSV F1)" in out and "F2 (CSV" not in out   # the printed names are mapped
        report = json.loads(report_path.read_text())
        assert list(report["per_robot_cm"]) == ["F2", "F3", "H"]
        assert report["csv_robot"] == {"F2": "F2", "F3": "F1", "H": "H"}
        assert report["n_instances"] == 6 and report["mean_error_cm"] > 0
        assert len(report["per_step_cm"]) == 16
    # --first-model: module 0 by another model (a split chain); one of another history: exit 2
    args = ["evaluate", "retlo", "--model", str(model), "--data", str(five)]
    code, out, err = _cli(capsys, *args, "--first-model", "heuristic2x", "--out",
                          str(tmp_path / "split.json"))
    assert code == 0, err
    assert json.loads((tmp_path / "split.json").read_text())["model"] == "fc after heuristic2x"
    short = tmp_path / "short.pt"
    code, _, err = _cli(capsys, "train", "retlo", "--model", "fc", "--train", str(train_csv),
                        "--val", str(val_csv), "--out", str(short), "--epochs", "1",
                        "--history", "5")
    assert code == 0, err
    code, _, err = _cli(capsys, *args, "--first-model", str(short), "--out",
                        str(tmp_path / "bad.json"))
    assert code == 2 and "history" in err and not (tmp_path / "bad.json").exists()


def test_experiment_writes_figures_video_and_results_identically(tmp_path, capsys):
    import cv2

    train_csv = write_csv(tmp_path / "train.csv", world_to_pixels(synthetic_chains(24, 3, 1), 3.0))
    val_csv = write_csv(tmp_path / "val.csv", world_to_pixels(synthetic_chains(6, 3, 2), 3.0))
    five = write_csv(tmp_path / "five.csv", world_to_pixels(synthetic_chains(4, 5, 3), 3.0))
    for out in (tmp_path / "exp", tmp_path / "again"):
        code, stdout, err = _cli(capsys, "experiment", "retlo", "--train",
                                 str(train_csv), "--val", str(val_csv), "--test", str(five),
                                 "--holdout", "0.25", "--seeds", "2", "--epochs", "1",
                                 "--out", str(out))
        assert code == 0, err
    results = json.loads((out / "results.json").read_text())
    assert [t["n_robots"] for t in results["tests"]] == [3, 5]
    lstm = results["results"]["five.csv"]["lstm"]
    assert len(lstm["per_seed_cm"]) == 2 and set(lstm["per_robot_cm"]) == {"F2", "F3", "H"}
    curves = results["fig2_9"]               # Fig 2.9's claims, on the 5-robot test
    assert curves["test"] == "five.csv"
    assert set(curves["lstm"]["inside_cm"]) == {"F2", "F3", "H", "pooled"}
    shares = curves["lstm"]["largest_error_share"]
    assert abs(sum(v["mean"] for v in shares.values()) - 1.0) < 1e-9
    for name in ("results.json", "fig2_7.png", "fig2_8.png", "fig2_9.mp4",
                 "models/lstm_seed1.pt"):
        assert (out / name).stat().st_size > 0
        assert (out / name).read_bytes() == (tmp_path / "exp" / name).read_bytes(), name
    assert (out / "manifest.json").is_file()
    video = cv2.VideoCapture(str(out / "fig2_9.mp4"))
    assert int(video.get(cv2.CAP_PROP_FRAME_COUNT)) == 3 * 26
    video.release()
    assert "lstm" in stdout and "% below FC" in stdout
    # --group 2: the two seeds of each model train together, to float rounding the same
    code, _, err = _cli(capsys, "experiment", "retlo", "--train", str(train_csv), "--val",
                        str(val_csv), "--test", str(five), "--holdout", "0.25", "--seeds", "2",
                        "--epochs", "1", "--group", "2", "--out", str(tmp_path / "grouped"))
    assert code == 0, err
    grouped = json.loads((tmp_path / "grouped" / "results.json").read_text())
    for kind in ("fc", "lstm"):
        assert grouped["results"]["five.csv"][kind]["per_seed_cm"] == pytest.approx(
            results["results"]["five.csv"][kind]["per_seed_cm"], rel=1e-3)


def test_experiment_cross_validates_over_train_and_val(tmp_path, capsys):
    """--folds: each seed is scored on its own block of the pooled train + val, which it never
    trained or selected on; the heuristic on every block."""
    train_csv = write_csv(tmp_path / "train.csv", world_to_pixels(synthetic_chains(24, 3, 1), 3.0))
    val_csv = write_csv(tmp_path / "val.csv", world_to_pixels(synthetic_chains(6, 3, 2), 3.0))
    code, stdout, err = _cli(capsys, "experiment", "retlo", "--train", str(train_csv), "--val",
                             str(val_csv), "--folds", "3", "--seeds", "3", "--epochs", "1",
                             "--out", str(tmp_path / "cv"))
    assert code == 0, err
    results = json.loads((tmp_path / "cv" / "results.json").read_text())
    (test,) = results["tests"]
    assert test["name"] == CV_TEST and test["n_instances"] == 30 and test["folds"] == 3
    cv = results["results"][CV_TEST]
    assert len(cv["lstm"]["per_seed_cm"]) == 3 and len(cv["heuristic2x"]["per_seed_cm"]) == 3
    assert results["fig2_9"]["test"] == CV_TEST
    assert CV_TEST in stdout
    code, _, err = _cli(capsys, "experiment", "retlo", "--train", str(train_csv), "--val",
                        str(val_csv), "--folds", "3", "--seeds", "1", "--epochs", "1",
                        "--uncertainty", "gaussian", "--out", str(tmp_path / "gauss"))
    assert code == 0, err
    gauss = json.loads((tmp_path / "gauss" / "results.json").read_text())["results"][CV_TEST]
    pooled = gauss["lstm"]["calibration"]["pooled"]
    assert 0 <= pooled["coverage_50"]["mean"] <= pooled["coverage_90"]["mean"] <= 1
    assert "calibration" not in gauss["heuristic2x"]
    code, _, err = _cli(capsys, "experiment", "retlo", "--train", str(train_csv), "--val",
                        str(val_csv), "--folds", "3", "--holdout", "0.2", "--out",
                        str(tmp_path / "both"))
    assert code == 2 and "--folds and --holdout" in err and not (tmp_path / "both").exists()


class _Counting(Heuristic2X):
    """The 2X heuristic, counting the estimates it makes (the windows it is given)."""

    def __init__(self, history: int = 10):
        self.history, self.calls = history, 0

    def estimate(self, x):
        self.calls += len(x[0])
        return super().estimate(x)


def test_a_split_chain_runs_its_first_model_at_module_0_only():
    """`SplitChain(first, rest)`: module 0 (the measured Follower) by `first`, every later
    module by `rest`; alone on 3 robots it is `first`; models of unlike history are refused."""
    world = synthetic_chains(4, 5, 3)
    first, rest = _Counting(), _Counting()
    split = predict_chain(SplitChain(first, rest), world)
    assert np.array_equal(split, predict_chain(Heuristic2X(), world), equal_nan=True)
    steps = world.shape[1] - first.history - 1          # module k runs steps - k of them
    assert first.calls == 4 * steps and rest.calls == 4 * ((steps - 1) + (steps - 2))
    first.calls = rest.calls = 0
    predict_chain(SplitChain(first, rest), synthetic_chains(4, 3, 3))
    assert first.calls > 0 and rest.calls == 0
    with pytest.raises(UserError, match="history"):
        SplitChain(_Counting(10), _Counting(5))
    fitted = _Counting()
    fitted.regions = "the first model's radii"          # calibration reads the first's regions
    assert SplitChain(fitted, _Counting()).regions == "the first model's radii"


def test_experiment_split_trains_both_and_refuses_it_unchained(tmp_path, capsys):
    train_csv = write_csv(tmp_path / "train.csv", world_to_pixels(synthetic_chains(24, 3, 1), 3.0))
    val_csv = write_csv(tmp_path / "val.csv", world_to_pixels(synthetic_chains(6, 3, 2), 3.0))
    five = write_csv(tmp_path / "five.csv", world_to_pixels(synthetic_chains(4, 5, 3), 3.0))
    args = ["experiment", "retlo", "--train", str(train_csv), "--val", str(val_csv), "--test",
            str(five), "--holdout", "0.25", "--seeds", "1", "--epochs", "1", "--split"]
    code, _, err = _cli(capsys, *args, "--out", str(tmp_path / "split"))
    assert code == 0, err
    models = sorted(p.name for p in (tmp_path / "split" / "models").iterdir())
    assert models == ["fc_seed0.pt", "first_fc_seed0.pt", "first_lstm_seed0.pt",
                      "lstm_seed0.pt"]
    manifest = json.loads((tmp_path / "split" / "manifest.json").read_text())
    assert manifest["config"]["split"] is True
    code, _, err = _cli(capsys, *args, "--no-chained", "--out", str(tmp_path / "bad"))
    assert code == 2 and "--split" in err and not (tmp_path / "bad").exists()


def _data(tmp_path):
    return str(write_csv(tmp_path / "d.csv", world_to_pixels(_rigid(3, "straight"), 3.0)))


def _bad_checkpoint(tmp_path):
    path = tmp_path / "other.pt"
    torch.save({"state_dict": {}, "kind": "dsvdd"}, path)
    return path


BAD_RUNS = {
    "two robots": (lambda p: ["evaluate", "retlo", "--model", "heuristic2x", "--data",
                              str(write_csv(p / "d.csv",
                                            world_to_pixels(_rigid(2, "straight"), 3.0))),
                              "--out", str(p / "r.json")], "at least 3"),
    "too few steps": (lambda p: ["evaluate", "retlo", "--model", "heuristic2x", "--data",
                                 str(write_csv(p / "d.csv", world_to_pixels(
                                     _rigid(3, "straight", n_steps=8), 3.0))),
                                 "--out", str(p / "r.json")], "steps"),
    "other checkpoint": (lambda p: ["evaluate", "retlo", "--model", str(_bad_checkpoint(p)),
                                    "--data", _data(p), "--out", str(p / "r.json")],
                         "not a ReTLo checkpoint"),
    "not torch": (lambda p: ["evaluate", "retlo", "--model", str(p / "r.json"), "--data",
                             _data(p), "--out", str(p / "q.json")], "not a readable torch"),
    "unknown eval model": (lambda p: ["evaluate", "retlo", "--model", "heuristic3x", "--data",
                                      _data(p), "--out", str(p / "r.json")], "unknown model"),
    "unknown train model": (lambda p: ["train", "retlo", "--model", "gru", "--train", _data(p),
                                       "--val", _data(p), "--out", str(p / "m.pt")],
                            "'--model': 'gru' is not one of fc, lstm"),
}


@pytest.mark.parametrize("case", list(BAD_RUNS))
def test_bad_input_exits_2_with_one_line(tmp_path, capsys, case):
    make_args, expected = BAD_RUNS[case]
    (tmp_path / "r.json").write_text("{}") if case == "not torch" else None
    code, out, err = _cli(capsys, *make_args(tmp_path))
    assert code == 2 and err.count("\n") == 1 and expected in err, err
    assert "Traceback" not in err
    assert not (tmp_path / "m.pt").exists() and not (tmp_path / "q.json").exists()


def test_files_are_read_in_metres():
    world = synthetic_chains(2, 3, seed=0)
    assert np.allclose(pixels_to_world(world_to_pixels(world, 3.0), 3.0), world)
    assert 0.25 < np.linalg.norm(world[0, 0, 0, :2] - world[0, 0, 1, :2]) < 0.4   # 31 cm


def test_the_networks_see_the_inputs_of_the_cm_pipeline():
    """The chain runs in metres; a network's float32 inputs equal those the same chains in cm
    gave it (the unit its checkpoints and figures were made in), but for the rounding residue of
    the Follower's y at t, exactly 0 in the rotated frame (about 1e-15 cm in either unit)."""
    world = synthetic_chains(4, 4, seed=5)[:, :, ::-1]
    cfg = ModelConfig(cos_sin=True)
    cm = world.copy()
    cm[..., :2] *= 100.0
    for k, t in ((0, 10), (1, 17)):
        ours = net_features(window(tracks_from_world(world, 26), k, t, 10, True), cfg)
        theirs = history_features(window(tracks_from_world(cm, 26), k, t, 10, True), True, True)
        for a, b in zip(ours, theirs, strict=True):
            zero = np.abs(b) < 1e-9
            assert np.array_equal(a.astype(np.float32)[~zero], b.astype(np.float32)[~zero])
            assert np.all(np.abs(a[zero]) < 1e-12)


@pytest.mark.parametrize("cos_sin", [False, True])
def test_mirror_signs_reflect_samples_like_a_reflected_chain(cos_sin):
    from estimators.retlo.train import make_samples, mirror_signs

    cfg = ModelConfig(cos_sin=cos_sin)
    world = synthetic_chains(4, 4, seed=5)
    reflected = world.copy()
    reflected[..., 1:] *= -1  # y → -y, θ → -θ
    signs = mirror_signs(cfg)
    ours, theirs = make_samples([world], cfg), make_samples([reflected], cfg)
    for key in ours:
        assert np.allclose(ours[key] * signs[key], theirs[key], atol=1e-4), key


def test_heuristic_on_the_real_data_matches_the_dissertation(reference_data):
    train_csv = reference_data / "ReTLo" / "Datasets" / "3Robots" / "Train.csv"
    report = evaluate_chain(Heuristic2X(), read_world(train_csv, 3.0))
    assert 23.0 < report["per_robot_cm"]["H"] < 26.0  # "about 24 cm" (§2.6.3.1, Fig 2.7)


def test_ctrl_c_during_training_keeps_the_best_checkpoint(tmp_path, capsys, monkeypatch):
    import estimators.retlo.train as train_module

    train_csv = write_csv(tmp_path / "train.csv", world_to_pixels(synthetic_chains(30, 3, 1), 3.0))
    val_csv = write_csv(tmp_path / "val.csv", world_to_pixels(synthetic_chains(8, 3, 2), 3.0))
    calls = []

    def validate_then_interrupt(pred, world):
        calls.append(1)
        if len(calls) == 3:          # the user presses Ctrl-C during the third epoch
            raise KeyboardInterrupt
        return evaluate_chain(pred, world)

    monkeypatch.setattr(train_module, "evaluate_chain", validate_then_interrupt)
    model = tmp_path / "fc.pt"
    code, _, err = _cli(capsys, "train", "retlo", "--model", "fc", "--train", str(train_csv),
                        "--val", str(val_csv), "--out", str(model), "--epochs", "10")
    assert code == 130 and "kept the best checkpoint" in err and err.strip().endswith(
        "interrupted")
    net, meta = load_checkpoint(model)
    assert meta["train_info"]["interrupted"] and meta["train_info"]["epochs_run"] == 2
    manifest = json.loads((tmp_path / "fc.pt.manifest.json").read_text())
    assert manifest["status"] == "interrupted"


def test_chapter_three_predictor_from_the_command_line(tmp_path, capsys):
    """§3.3's variant: a unidirectional LSTM, angles as cos/sin, and the history ℓ chosen."""
    train_csv = write_csv(tmp_path / "train.csv", world_to_pixels(synthetic_chains(20, 3, 1), 3.0))
    val_csv = write_csv(tmp_path / "val.csv", world_to_pixels(synthetic_chains(6, 3, 2), 3.0))
    model = tmp_path / "ch3.pt"
    code, _, err = _cli(capsys, "train", "retlo", "--model", "lstm", "--train", str(train_csv),
                        "--val", str(val_csv), "--out", str(model), "--epochs", "1",
                        "--unidirectional", "--cos-sin", "--history", "6")
    assert code == 0, err
    _, ckpt = load_checkpoint(model)
    cfg = ckpt["model_config"]
    assert (cfg["history"], cfg["bidirectional"], cfg["cos_sin"]) == (6, False, True)
    code, _, err = _cli(capsys, "evaluate", "retlo", "--model", str(model), "--data",
                        str(val_csv), "--out", str(tmp_path / "r.json"))
    assert code == 0, err
    assert json.loads((tmp_path / "r.json").read_text())["first_step"] == 6


def test_chained_samples_give_the_follower_an_estimate_error_and_keep_the_targets():
    from estimators.retlo.train import as_chained

    world = synthetic_chains(6, 3, 5)
    est = np.full_like(world, np.nan)
    est[:, 10:-1, 0, :2] = world[:, 10:-1, 0, :2] + np.arange(6)[:, None, None] + 1.0
    out = as_chained(world, est, np.random.default_rng(0))
    shift = out[:, :, 1, :2] - world[:, :, 1, :2]
    assert np.array_equal(out[:, :, [0, 2]], world[:, :, [0, 2]])      # Head, Tail: true
    assert np.all(shift[:, :10] == 0) and np.all(shift[:, -1] == 0)    # known before τ
    per_instance = shift[:, 10, 0] - 1.0
    assert sorted(per_instance) == list(range(6))                      # another's error each
    assert not np.array_equal(per_instance, np.arange(6))
