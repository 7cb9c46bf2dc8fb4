"""The Tail as an agent: the dm_control environment and its Gymnasium view, as an RL user tries
them (gymnasium.make, check_env, seeding, vector envs, rendering, bad actions)."""

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import macrostate_mj.env  # noqa: F401  (registers the ids)
from macrostate_mj.core.errors import UserError
from macrostate_mj.env.suite import SUITE, load

ID = "macrostate_mj/ExploreTail-v0"


@pytest.mark.parametrize("observe", ["truth", "camera"])
def test_check_env_passes(observe):
    env = gymnasium.make(ID, observe=observe, render_mode="rgb_array")
    try:
        check_env(env.unwrapped, skip_render_check=False)       # raises on any breach
        obs, _ = env.reset(seed=0)
        assert env.observation_space.contains(obs)
    finally:
        env.close()


def _rollout(seed: int, steps: int = 40, **kw) -> np.ndarray:
    env = gymnasium.make(ID, **kw)
    try:
        obs, _ = env.reset(seed=seed)
        env.action_space.seed(seed)
        out = [np.concatenate([obs["tail"][-1], obs["neighbour"][-1]])]
        for _ in range(steps):
            obs, reward, term, trunc, _ = env.step(env.action_space.sample())
            out.append(np.concatenate([obs["tail"][-1], obs["neighbour"][-1], [reward]]))
            if term or trunc:
                break
        return np.concatenate(out)
    finally:
        env.close()


def test_same_seed_same_episode_other_seed_another():
    for seed in (0, 5, 11):
        assert np.array_equal(_rollout(seed), _rollout(seed))
    assert not np.array_equal(_rollout(0), _rollout(1))


def test_the_action_moves_the_tail():
    """Offsetting the destination to the Tail's left for 5 s puts it left of where the
    passive Tail drives (the SRS control, §3.3)."""
    env = load("explore", robots=3, random=4)
    task = env.task
    left = np.array([0.0, task.max_offset])
    finals = []
    for offset in (np.zeros(2), left):
        env.task.random.seed(4)
        env.reset()
        for _ in range(20):
            env.step(offset)
        finals.append(task.sim.poses[-1, :2])
    assert np.linalg.norm(finals[1] - finals[0]) > 0.05


def test_two_copies_run_in_an_async_vector_env():
    envs = gymnasium.vector.AsyncVectorEnv([lambda: gymnasium.make(ID)] * 2)
    try:
        obs, _ = envs.reset(seed=[1, 2])
        assert obs["tail"].shape == (2, 10, 3)
        for _ in range(5):
            obs, reward, term, trunc, _ = envs.step(envs.action_space.sample())
        assert reward.shape == (2,) and not np.array_equal(obs["tail"][0], obs["tail"][1])
    finally:
        envs.close()


def test_render_is_the_overhead_camera():
    env = gymnasium.make(ID, render_mode="rgb_array")
    try:
        env.reset(seed=0)
        frame = env.render()
        assert frame.shape == (570, 750, 3) and frame.dtype == np.uint8 and frame.std() > 5
    finally:
        env.close()


def test_bad_input():
    env = gymnasium.make(ID)
    try:
        env.reset(seed=0)
        with pytest.raises(gymnasium.error.InvalidAction):
            env.step(np.array([5.0, 0.0]))
    finally:
        env.close()
    with pytest.raises(UserError, match="unknown task"):
        load("cage-the-moon")
    with pytest.raises(UserError, match="observe="):
        load(observe="sonar")
    with pytest.raises(UserError, match="do not fit"):
        load(scenario="robotarium", robots=400)


def test_the_suite_names_each_task_once_and_gymnasium_reaches_it_publicly():
    """`SUITE` is the one registry; the Gymnasium view exposes its task (and simulation), and
    seeding through it repeats the task's own draws."""
    assert set(SUITE) == {"explore", "caging", "localize"}
    for env_id, name in ((ID, "explore"), ("macrostate_mj/CagingTail-v0", "caging"),
                         ("macrostate_mj/LocalizeTail-v0", "localize")):
        env = gymnasium.make(env_id, time_limit=5.0)
        try:
            env.reset(seed=3)
            task = env.unwrapped.task
            assert type(task) is SUITE[name] and task.sim is env.unwrapped.environment.task.sim
        finally:
            env.close()
    env = load("explore", random=9)
    first = env.reset().observation["tail"]
    env.task.seed(9)
    assert np.array_equal(env.reset().observation["tail"], first)


@pytest.mark.parametrize("env_id", [ID, "macrostate_mj/CagingTail-v0",
                                    "macrostate_mj/LocalizeTail-v0"])
def test_a_short_ppo_run_trains_without_error(env_id):
    sb3 = pytest.importorskip("stable_baselines3")   # an optional extra
    env = gymnasium.wrappers.FlattenObservation(gymnasium.make(env_id))
    model = sb3.PPO("MlpPolicy", env, n_steps=256, batch_size=64, seed=0, device="cpu")
    model.learn(total_timesteps=1024)
    obs, _ = env.reset(seed=1)
    action, _ = model.predict(obs, deterministic=True)
    env.close()
    assert model.num_timesteps >= 1024
    assert action.shape == (2,) and np.all(np.isfinite(action))


def test_a_camera_episode_reports_its_tracking_health():
    env = load("explore", robots=3, random=2, observe="camera")
    try:
        env.reset()
        for _ in range(8):
            env.step(np.zeros(2))
        health = env.task.tracking_health()
        assert [r.robot for r in health.robots] == ["H", "F1", "T"]
        assert all(r.frames > 0 and r.detected_frames >= 0.9 for r in health.robots)
        assert health.judged(env.task.sim.cfg) == []
    finally:
        env.close()
    assert load("explore", robots=3, random=2).task.tracking_health() is None
