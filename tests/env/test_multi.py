"""Two Tails in one team (§5.2): the Head leading two chains, its PettingZoo environment (API,
seeding, bad input) and `experiment caging-multi` (the cooperating Tails cage; passive ones do
not)."""

import json
import subprocess
import sys

import gymnasium
import numpy as np
import pytest
from clitools import cli

from macrostate_mj.chain.caging_mission import CagingConfig, start_poses
from macrostate_mj.chain.team import ring_order, split_branches, team_start_poses
from macrostate_mj.core.errors import UserError

pytest.importorskip("pettingzoo")

from macrostate_mj.env.multi import parallel_env  # noqa: E402


def test_the_team_is_a_head_leading_two_chains_that_ring_through_it():
    a, b = split_branches(6, 2)
    assert a.tolist() == [0, 1, 2, 3] and b.tolist() == [0, 4, 5]
    assert ring_order([a, b]).tolist() == [3, 2, 1, 0, 4, 5]
    start = team_start_poses(CagingConfig(), [a, b], 0.08, np.random.default_rng(4))
    line = start_poses(CagingConfig(), 6, 0.08, np.random.default_rng(4))
    assert np.array_equal(start[0], line[0])            # a seed puts both Heads in one place
    for chain in (a, b):
        gaps = np.linalg.norm(np.diff(start[chain, :2], axis=0), axis=1)
        assert np.allclose(gaps, 0.08)
    # given the arena, a line drawn out through a wall is mirrored for the team as for one
    # chain: every robot inside, the Head still where the one-chain Head starts
    arena, half, mirrored = (1.2, 0.7), np.array([0.6, 0.35]), 0
    for seed in range(600):
        team = team_start_poses(CagingConfig(), [a, b], 0.08, np.random.default_rng(seed),
                                arena)
        line = start_poses(CagingConfig(), 6, 0.08, np.random.default_rng(seed), arena)
        assert np.all(np.abs(team[:, :2]) <= half) and np.array_equal(team[0], line[0])
        mirrored += not np.array_equal(team, team_start_poses(
            CagingConfig(), [a, b], 0.08, np.random.default_rng(seed)))
    assert mirrored >= 1


def test_pettingzoo_api_and_seed_tests_pass():
    from pettingzoo.test import parallel_api_test, parallel_seed_test

    env = parallel_env(time_limit=2.0)
    assert env.possible_agents == ["tail_0", "tail_1"]
    parallel_api_test(env, num_cycles=100)
    env.close()
    parallel_seed_test(lambda: parallel_env(time_limit=2.0), num_cycles=50)


def _episode(seed: int, steps: int = 45) -> tuple[list, np.ndarray]:
    env = parallel_env(time_limit=10.0)
    obs, _ = env.reset(seed=seed)
    rng = np.random.default_rng(0)
    seen = []
    for _ in range(steps):
        actions = {a: rng.uniform(-0.16, 0.16, 2).astype(np.float32) for a in env.agents}
        obs, rewards, *_ = env.step(actions)
        seen.append((obs, rewards))
    poses = env.task.sim.poses
    env.close()
    return seen, poses


def test_a_seed_repeats_its_episode_bit_for_bit_and_another_does_not():
    (one, p1), (two, p2), (_, p3) = _episode(3), _episode(3), _episode(4)
    assert np.array_equal(p1, p2) and not np.array_equal(p1, p3)
    for (o1, r1), (o2, r2) in zip(one, two, strict=True):
        assert r1 == r2
        for agent in o1:
            assert all(np.array_equal(o1[agent][k], o2[agent][k]) for k in o1[agent])


def test_each_tail_observes_its_own_chain_and_acts_on_it():
    env = parallel_env(time_limit=5.0)
    obs, infos = env.reset(seed=1)
    sim = env.task.sim
    for i, agent in enumerate(env.possible_agents):
        assert env.observation_space(agent).contains(obs[agent])
        assert np.array_equal(obs[agent]["tail"][-1], sim.poses[sim.tails[i]])
        assert np.array_equal(obs[agent]["neighbour"][-1], sim.poses[sim.neighbours[i]])
    assert infos["tail_0"]["team_at_start"].shape == (6, 3)
    env.step({"tail_0": np.array([0.1, 0.0], np.float32), "tail_1": np.zeros(2, np.float32)})
    assert np.allclose(sim.tail_offset, [[0.1, 0.0], [0.0, 0.0]])
    env.close()


def test_through_the_camera_each_tail_sees_its_own_neighbour():
    env = parallel_env(observe="camera", render_mode="rgb_array", time_limit=1.0)
    env.reset(seed=2)
    for _ in range(3):
        obs, *_ = env.step({a: np.zeros(2, np.float32) for a in env.agents})
    sim = env.task.sim
    for i, agent in enumerate(env.possible_agents):
        seen = obs[agent]["neighbour"][-1, :2]
        assert np.linalg.norm(seen - sim.poses[sim.neighbours[i], :2]) < 0.01
    assert env.render().ndim == 3
    env.close()


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"task": "explore"}, "unknown team task"),
    ({"tails": 3, "robots": 7}, "tails must be 2"),
    ({"tails": 1}, "at least 2"),
    ({"robots": 4}, "at least 5 robots"),
    ({"render_mode": "human"}, "render_mode"),
    ({"time_limit": -1.0}, "time_limit"),
])
def test_bad_arguments_are_refused_in_one_line(kwargs, match):
    with pytest.raises(UserError, match=match) as err:
        parallel_env(**kwargs)
    assert "\n" not in str(err.value)


def test_bad_actions_are_refused_inside_the_api():
    env = parallel_env(time_limit=2.0)
    env.reset(seed=0)
    ok = np.zeros(2, np.float32)
    with pytest.raises(gymnasium.error.InvalidAction, match="tail_1's action"):
        env.step({"tail_0": ok, "tail_1": np.array([0.5, 0.0], np.float32)})
    with pytest.raises(gymnasium.error.InvalidAction, match="no action for tail_1"):
        env.step({"tail_0": ok})
    env.close()


def test_the_core_env_does_not_need_pettingzoo():
    code = ("import sys, macrostate_mj, macrostate_mj.env.suite, macrostate_mj.env.gym; "
            "assert 'pettingzoo' not in sys.modules")
    assert subprocess.run([sys.executable, "-c", code]).returncode == 0


def test_two_cooperating_tails_cage_and_passive_ones_do_not():
    from macrostate_mj.app.experiments.caging_multi import Config, run_episode

    cfg = Config(time_limit=25.0)
    two = run_episode("two_tails", 1000, cfg)
    assert two["caged"] and two["detected_at_s"] < two["time_to_cage_s"]
    assert not run_episode("two_passive", 1000, cfg)["caged"]


def test_experiment_caging_multi_quick(tmp_path):
    out = tmp_path / "multi"
    res = cli("experiment", "caging-multi", "--quick", "--seeds", "1", "--first-seed", "1000",
              "--time-limit", "25", "--out", str(out))
    assert res.returncode == 0, res.stderr
    results = json.loads((out / "results.json").read_text())
    assert set(results["table"]) == {"one_tail", "two_tails", "two_passive", "one_tail_retlo",
                                     "two_tails_retlo"}
    assert results["table"]["two_tails"]["success_rate"] == 1.0
    oracle = results["paired"]["oracle"]
    assert oracle["seeds"] == 1 and oracle["both_caged"] == 1
    assert set(results["paired"]) == {"oracle", "retlo", "scripted_vs_retlo"}
    # the estimated arms score their Head estimates; the oracle-fed ones have none
    assert results["table"]["two_tails_retlo"]["head_estimate_error_m"]["n"] == 1
    assert results["table"]["two_tails"]["head_estimate_error_m"]["n"] == 0
    assert (out / "manifest.json").exists()


def test_the_team_rehearsals_are_every_chains_consecutive_triples():
    """The two-chain ReTLo arm's estimator rehearses on the team: each chain's three-robot
    windows, Head first (chains H-A1-A2-TA and H-B1-TB: three triples, two holding the Head)."""
    from collectors.caging_runs import team_rehearsal_runs

    runs = team_rehearsal_runs(1, 3.0)
    assert runs.shape[0] == 3 and runs.shape[2:] == (3, 3)
    heads = runs[:, :, 0]
    assert np.array_equal(heads[0], heads[2]) and not np.array_equal(heads[0], heads[1])
