"""The caging mission (§2.5.4): its geometry and judge, the environment, and what must hold over
seeds (a passive Tail never cages; the oracle Tail does)."""

import gymnasium
import numpy as np
import pytest
from clitools import cli

import macrostate_mj.env  # noqa: F401  (registers the ids)
from macrostate_mj.chain.caging_mission import (
    CagingConfig,
    cage_report,
    circling_centre,
    fit_circle,
    offset_for_velocity,
    start_poses,
    winding_number,
)
from macrostate_mj.chain.motion import pull
from macrostate_mj.core.errors import UserError
from macrostate_mj.env.suite import load

CFG = CagingConfig()


def _ring(n: int, radius: float, shift=(0.0, 0.0), phase: float = 0.3) -> np.ndarray:
    a = phase + 2 * np.pi * np.arange(n) / n
    return np.column_stack([radius * np.cos(a) + shift[0], radius * np.sin(a) + shift[1],
                            np.zeros(n)])


def test_the_judge_cages_an_even_ring_and_nothing_else():
    even = cage_report(_ring(6, CFG.ring_radius), CFG)
    assert even["caged"] and even["enclosed"]
    assert even["max_gap_deg"] == pytest.approx(60) and even["spacing_cv"] < 1e-9
    assert not cage_report(_ring(6, CFG.ring_radius, shift=(0.2, 0.0)), CFG)["enclosed"]
    bunched = _ring(6, CFG.ring_radius)[[0, 1, 2, 3, 2, 1]]       # folded back on itself
    assert not cage_report(bunched, CFG)["caged"]
    assert winding_number(_ring(6, 1.0)[:, :2], np.zeros(2)) == 1
    assert winding_number(_ring(6, 1.0)[::-1, :2], np.zeros(2)) == -1


def test_circling_is_found_only_over_enough_of_a_circle():
    centre = np.array([0.03, -0.02])
    arc = lambda deg: centre + CFG.ring_radius * np.column_stack(   # noqa: E731
        [np.cos(np.radians(np.linspace(0, deg, 60))), np.sin(np.radians(np.linspace(0, deg, 60)))])
    c, r, rms = fit_circle(arc(90))
    assert np.allclose(c, centre) and r == pytest.approx(CFG.ring_radius) and rms < 1e-9
    assert circling_centre(arc(90), CFG) is None
    assert np.allclose(circling_centre(arc(180), CFG), centre)
    line = np.column_stack([np.linspace(0, 0.2, 60), np.zeros(60)])
    assert circling_centre(line, CFG) is None


def test_the_action_inverts_the_tail_rule():
    tail, fol = np.array([0.0, 0.0, 0.0]), np.array([0.09, 0.02])
    u = np.array([-0.03, 0.05])
    w = offset_for_velocity(u, tail, fol, 0.08, 40.0, 1.0)
    rule = 40.0 * pull(tail[:2], fol, 0.08) + 40.0 * np.linalg.norm(fol - tail[:2]) * w
    assert np.allclose(rule, u)
    assert np.all(np.abs(offset_for_velocity(100 * u, tail, fol, 0.08, 40.0, 0.16)) <= 0.16)


def test_caging_env_passes_the_checker_and_repeats_with_its_seed():
    from gymnasium.utils.env_checker import check_env

    env = gymnasium.make("macrostate_mj/CagingTail-v0", time_limit=5.0)
    check_env(env.unwrapped)
    runs = []
    for _ in range(2):
        obs, info = env.reset(seed=5)
        assert info["team_at_start"].shape == (6, 3)
        for _ in range(40):
            obs, reward, terminated, truncated, info = env.step(
                np.array([0.05, -0.02], np.float32))
        runs.append(obs["tail"])
    assert np.array_equal(*runs)
    env.close()
    with pytest.raises(UserError, match="does not fit"):
        load("caging", "robotarium", 6, caging=CagingConfig(ring_radius=0.4))


def test_the_tail_senses_the_object_only_within_its_sensor_radius():
    env = gymnasium.make("macrostate_mj/CagingTail-v0", time_limit=5.0)
    obs, _ = env.reset(seed=1)
    assert np.array_equal(obs["object"], np.zeros(3))          # starts in the far corner
    task = env.unwrapped.task
    reach = CFG.object_radius + CFG.sensor_radius
    near = task.sense_object(np.array([reach - 0.01, 0.0]))
    assert np.allclose(near, [-(reach - 0.01), 0.0, 1.0])
    assert np.array_equal(task.sense_object(np.array([0.0, reach + 0.01])), np.zeros(3))
    env.close()


def test_the_retlo_tail_receives_the_shared_poses():
    """The team's poses shared at a tick reach the Tail's estimator at that very step: with a
    module that knows nothing (it predicts zeros), the Head estimate of a sync step is the truth."""
    from estimators.retlo.mlp import OneStepModule
    from estimators.retlo.online import OnlineChain
    from macrostate_mj.tails.caging import LiveHeadSource

    class Blind(OneStepModule):
        def predict(self, base: np.ndarray) -> np.ndarray:
            return np.zeros((len(base), 3))

    env = gymnasium.make("macrostate_mj/CagingTail-v0", time_limit=20.0)
    obs, info = env.reset(seed=2)
    sim, stride = env.unwrapped.task.sim, 30
    blind = OnlineChain(Blind(), sim.n, int(20.0 * sim.cfg.command_hz / stride) + 2)
    source = LiveHeadSource(blind, info["team_at_start"], stride)
    share = int(round(CFG.share_every_s * sim.cfg.command_hz))
    heads = []
    for _ in range(share + (sim.n - 2) * stride + 1):
        heads.append(sim.poses[0, :2].copy())
        source(obs, info)
        obs, *_, info = env.step(np.zeros(2, np.float32))
    tick, head = source.latest()
    assert tick == share and np.allclose(head, heads[share])
    env.close()


def test_a_passive_tail_never_cages_and_the_oracle_does():
    """Over 3 seeds: the dissertation's claim that Head and Followers alone cannot cage, and
    that a Tail which encircles against the Head, once it knows the Head circles, can."""
    from macrostate_mj.app.experiments.caging import Config, run_episode

    cfg = Config(time_limit=45.0)
    passive = [run_episode("passive", s, cfg)["caged"] for s in range(3)]
    oracle = [run_episode("oracle", s, cfg) for s in range(3)]
    assert not any(passive)
    assert sum(e["caged"] for e in oracle) >= 2
    assert all(e["spacing_cv"] < 0.1 for e in oracle if e["caged"])


def test_experiment_caging_quick(tmp_path):
    import json

    out = tmp_path / "cage"
    res = cli("experiment", "caging", "--quick", "--out", str(out))
    assert res.returncode == 0, res.stderr
    results = json.loads((out / "results.json").read_text())
    assert set(results["table"]) == {"passive", "retlo", "oracle", "random"}
    assert results["table"]["oracle"]["success_rate"] > results["table"]["passive"]["success_rate"]
    for name in ("snapshots.png", "oracle_seed0.mp4", "retlo_seed0.mp4", "retlo_seed0.rrd"):
        assert (out / name).stat().st_size > 1000


def test_a_start_drawn_into_a_wall_heads_the_mirrored_way():
    """About 1 start in 180 headed 6 robots out through the robotarium's bottom wall (a reset
    then failed); given the arena, such a draw mirrors its heading, and every other draw is
    the same as without it."""
    arena, half = (1.2, 0.7), np.array([0.6, 0.35])
    moved = 0
    for seed in range(2000):
        plain = start_poses(CagingConfig(), 6, 0.08, np.random.default_rng(seed))
        fitted = start_poses(CagingConfig(), 6, 0.08, np.random.default_rng(seed), arena)
        assert np.all(np.abs(fitted[:, :2]) <= half)
        if np.any(np.abs(plain[:, :2]) > half):
            moved += 1
            assert np.allclose(fitted[:, 2], -plain[:, 2])
        else:
            assert np.array_equal(fitted, plain)
    assert moved >= 1
