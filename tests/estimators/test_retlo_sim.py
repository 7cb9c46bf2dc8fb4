"""`experiment retlo-sim` (§2.5): data generation, the chained MLPs, modular estimation, CLI."""

import json

import numpy as np
import pytest
from clitools import cli_inprocess as _cli

from collectors.robotarium import (
    fit_start,
    noisy_replicas,
    run_chain,
    training_runs,
    twists_of,
)
from collectors.robotarium_cases import tail_view
from estimators.retlo.chain import estimate_chain, sync_steps
from estimators.retlo.heuristic import estimate_heuristic
from estimators.retlo.mlp import (
    OneStepModule,
    init_mlp,
    mse,
    standardize,
    train_mlp,
    training_pairs,
)
from estimators.retlo.online import OnlineChain
from estimators.retlo.report import chain_errors, one_step_errors
from macrostate_mj.chain.scenarios import get_scenario
from macrostate_mj.chain.world import build_world
from macrostate_mj.core.frames import frame_of, from_frame, to_frame

CFG = get_scenario("robotarium")


def rigid_straight(n: int, steps: int, heading: float, spacing: float,
                   speed: float = 0.001) -> np.ndarray:
    """(steps, n, 3) Head-first poses of a rigid chain driving straight, `speed` m per step."""
    u = np.array([np.cos(heading), np.sin(heading)])
    xy = (np.arange(steps)[:, None, None] * speed - np.arange(n)[None, :, None] * spacing) * u
    return np.concatenate([xy, np.full((steps, n, 1), heading)], axis=-1)


def test_training_data_shapes_and_determinism():
    runs = training_runs(CFG, 12)
    assert runs.shape == (20, 12, 3, 3) and np.all(np.isfinite(runs))
    noisy = noisy_replicas(runs, 5, 0.001, np.random.default_rng(3))
    assert noisy.shape == (20, 5, 12, 3, 3)
    assert 0.0008 < np.std(noisy - runs[:, None]) < 0.0012
    assert np.array_equal(noisy, noisy_replicas(runs, 5, 0.001, np.random.default_rng(3)))
    base, targets = training_pairs(noisy)
    assert base.shape == (20 * 5 * 11, 5) and targets.shape == (20 * 5 * 11, 3)
    # The same treatment simulated again gives the same poses, bit for bit.
    sched = ((0, 3),)
    start, room = fit_start(CFG, 3, twists_of(sched, 12))
    assert room > 0
    again = run_chain(build_world(CFG, 3), start, 12, CFG.k_t * 0.25, sched)
    assert np.array_equal(again, runs[12])     # preset 3 × the first k_t factor


def test_frame_round_trip_and_rigid_features():
    rng = np.random.default_rng(0)
    xy, ref, fol = rng.normal(size=(3, 7, 2))
    origin, alpha = frame_of(ref, fol)
    assert np.allclose(from_frame(to_frame(xy, origin, alpha), origin, alpha), xy)
    base, targets = training_pairs(rigid_straight(3, 5, 2.0, 0.08)[None])
    assert np.allclose(base[:, [0, 1, 2, 4]], [0.08, 0, 0, 0]) and np.allclose(base[:, 3], 0.081)
    assert np.allclose(targets, [0.16, 0.0, 0.0])


class ExactStraight(OneStepModule):
    """The known answer on a rigid straight chain: Head at twice the Follower, heading kept."""

    def predict(self, base: np.ndarray) -> np.ndarray:
        return np.column_stack([2 * base[:, 0], 2 * base[:, 1], base[:, 2]])


@pytest.mark.parametrize("n", [3, 4, 6])
def test_modular_estimation_is_exact_with_the_known_module(n):
    poses = rigid_straight(n, 40, 0.7, 0.08)
    sync = sync_steps(40, None)
    sensed, synced, truth = tail_view(poses, sync, 0.0, None)
    err = chain_errors(estimate_chain(ExactStraight(), sensed, synced, sync), truth)
    assert err.shape == (40, n - 2)
    assert np.nanmax(err) < 1e-12
    # Module k stops k steps before the end: far robots lag (§2.5.1.2), nothing is invented.
    assert np.isfinite(err[1:40 - (n - 2), -1]).all() and np.isnan(err[40 - (n - 2):, -1]).all()
    h_err = chain_errors(estimate_heuristic(sensed, synced, sync), truth)
    assert np.nanmax(h_err) < 1e-12
    assert one_step_errors(ExactStraight(), truth).max() < 1e-12


def _rigid_training(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    chains = [rigid_straight(3, 30, rng.uniform(-np.pi, np.pi), rng.uniform(0.08, 0.11))
              for _ in range(40)]
    noisy = noisy_replicas(np.stack(chains), 2, 0.0002, rng)
    return training_pairs(noisy)


def test_training_lowers_the_error_and_the_trained_chain_is_accurate():
    rng = np.random.default_rng(0)
    base, targets = _rigid_training(rng)
    before = init_mlp(*standardize_pair(base, targets), np.random.default_rng(1))
    model, history = train_mlp(base, targets, np.random.default_rng(1), epochs=40, lr=0.05,
                               momentum=0.2, batch=32)
    assert history[-1].sum() < 0.2 * history[0].sum()
    assert mse(model, base, targets).sum() < 0.1 * mse(before, base, targets).sum()
    # A 6-robot rigid chain in a heading never seen: every robot well within the diameter.
    poses = rigid_straight(6, 200, 1.234, 0.095)
    sync = sync_steps(200, None)
    sensed, synced, truth = tail_view(poses, sync, 0.0, None)
    err = chain_errors(estimate_chain(model, sensed, synced, sync), truth)
    assert np.nanmax(err) < 0.01, np.nanmax(err, axis=0)


def standardize_pair(base: np.ndarray, targets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Raw training inputs (base plus true x_H, y_H) and targets, as `init_mlp` takes them."""
    return np.concatenate([base, targets[:, :2]], axis=1), targets


def test_standardize_matches_init_statistics():
    base, targets = _rigid_training(np.random.default_rng(2))
    m = init_mlp(*standardize_pair(base, targets), np.random.default_rng(0))
    x, y = standardize(m, base, targets)
    assert np.allclose(y.mean(0), 0, atol=1e-9) and np.allclose(x[:, 1], 0)


def test_experiment_end_to_end_is_deterministic(tmp_path, capsys):
    args = ["experiment", "retlo-sim", "--epochs", "1", "--train-steps", "20",
            "--test-steps", "40", "--seed", "5"]
    code, out, err = _cli(capsys, *args, "--out", str(tmp_path / "a"))
    assert code == 0, err
    assert "(a) straight, 6 robots" in out and "(f)" in out
    res = json.loads((tmp_path / "a" / "results.json").read_text())
    assert set(res["cases"]) == set("abcdef")
    for key, n in zip("abcdef", [6, 5, 6, 6, 5, 6], strict=True):
        case = res["cases"][key]
        assert list(case["per_robot"]) == [*(f"F{j}" for j in range(2, n - 1)), "H"]
        assert all(0 <= r["share_under"] <= 1 and r["mean_error"] >= 0
                   for r in case["per_robot"].values())
        assert (tmp_path / "a" / f"case_{key}.png").stat().st_size > 1000
    assert res["cases"]["d"]["comm_every"] == 150 and res["cases"]["f"]["noisy"]
    manifest = json.loads((tmp_path / "a" / "manifest.json").read_text())
    assert manifest["seed"] == 5 and manifest["config"]["epochs"] == 1
    code, _, err = _cli(capsys, *args, "--out", str(tmp_path / "b"))
    assert code == 0, err
    per_step = json.loads((tmp_path / "a" / "per_step_errors.json").read_text())
    assert len(per_step["c"]["H"]) == 40 and per_step["c"]["H"][0] is None
    for name in ["results.json", "per_step_errors.json", "case_c.png", "trajectories.png"]:
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes()


@pytest.mark.parametrize("bad", [["--epochs", "0"], ["--test-steps", "5"], ["--existing"],
                                 ["--train-steps", "2000"]])
def test_bad_input_exits_2_with_one_line(tmp_path, capsys, bad):
    if bad == ["--existing"]:
        (tmp_path / "results.json").write_text("{}")
        bad = []
    code, out, err = _cli(capsys, "experiment", "retlo-sim", "--out", str(tmp_path),
                          "--train-steps", "20", "--test-steps", "40", *bad)
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err, err
    assert not (tmp_path / "manifest.json").exists()


@pytest.mark.parametrize("comm_every", [None, 7])
def test_the_online_chain_estimates_what_the_offline_one_does(comm_every):
    """The Tail's live estimator (one observation a step, the team's poses shared at the sync
    steps) equals `estimate_chain` on the same observations, for any module function, and its
    Head lags n - 2 steps."""
    rng = np.random.default_rng(3)
    steps, n = 40, 6
    truth = np.cumsum(rng.normal(0, 0.01, (steps, n, 3)), axis=0)

    class AnyModule(OneStepModule):                    # any deterministic module will do
        def predict(self, base: np.ndarray) -> np.ndarray:
            return np.column_stack([np.tanh(base.sum(1)), 0.3 * base[:, 0], np.sin(base[:, 1])])

    sync = sync_steps(steps, comm_every)
    offline = estimate_chain(AnyModule(), truth[:, :2, :2], truth[sync], sync)
    live = OnlineChain(AnyModule(), n, steps)
    live.start(truth[0])
    for s in range(1, steps):
        live.observe(truth[s, :2, :2])
        if s in sync:
            live.share(truth[s])
        t, head = live.head
        assert t == max(0, s - (n - 2))
        assert np.array_equal(head, offline[t, -1], equal_nan=True)
    assert np.array_equal(live.pos, offline, equal_nan=True)


def test_the_straight_test_chain_runs_on_an_open_floor():
    """Fig 2.2's 1,600-step straight run cannot fit between the robotarium walls: it runs with
    no walls (its start poses lie beyond them, which a walled world refuses)."""
    from collectors.robotarium_cases import case_run
    from macrostate_mj.chain.scenarios import get_scenario

    poses, floor = case_run(get_scenario("robotarium"), 6, "straight", 1600)
    assert floor == "open" and poses.shape == (1600, 6, 3) and np.isfinite(poses).all()
