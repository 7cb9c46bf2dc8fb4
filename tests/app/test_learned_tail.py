"""`experiment learned-tail`: the quick profile end to end through the CLI, a rerun that reuses
the trained policy, a killed training that continues from its last save, and bad input."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
from clitools import assert_clean_error, cli

pytest.importorskip("stable_baselines3")


def test_quick_runs_end_to_end_then_reuses_its_policy(tmp_path):
    out = tmp_path / "lt"
    res = cli("experiment", "learned-tail", "--quick", "--out", str(out))
    assert res.returncode == 0, res.stderr
    results = json.loads((out / "results.json").read_text())
    table = results["table"]
    assert set(table) == {"passive", "random", "srs_med", "chain_offset", "learned"}
    novelty = results["srs_novelty"]                  # SRS-Med's models, from its RO phase
    assert Path(novelty["path"]).is_file() and len(novelty["sha256"]) == 64
    assert len(results["estimator_sha256"]) == 64     # the env's default estimator, by content
    for row in table.values():
        assert row["seeds"] == 2 and row["head_error_m"]["n"] == 2
        assert row["spacing_m"]["mean"] > 0 and 0 <= row["breaks"] <= 2
    assert table["passive"]["vs_passive"]["mean_difference"] == 0.0
    assert {e["seed"] for e in results["episodes"]} == {0, 1}          # held out from training
    assert (out / "learning_curve.png").stat().st_size > 0
    for policy in table:                # seed 0 of each Tail, with the estimates drawn
        video = cv2.VideoCapture(str(out / "episodes" / f"{policy}_seed0.mp4"))
        assert int(video.get(cv2.CAP_PROP_FRAME_COUNT)) > 10
        video.release()
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["status"] == "finished" and manifest["steps_run_now"] == 512

    again = cli("experiment", "learned-tail", "--quick", "--out", str(out), "--overwrite")
    assert again.returncode == 0, again.stderr
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["steps_run_now"] == 0 and manifest["resumed_from"] == 512
    assert json.loads((out / "results.json").read_text())["table"]["learned"] == table["learned"]


def test_a_killed_training_continues_from_its_last_save(tmp_path):
    from macrostate_mj.tails.ppo import PPOSpec, train

    spec = PPOSpec(timesteps=768, envs=2, n_steps=128, batch_size=64, save_every=256,
                   time_limit=10.0)

    def kill(done: int, total: int) -> None:
        if done >= 512:                  # after the save at 256, before the one at 512
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        train(spec, None, tmp_path, report=kill)
    assert json.loads((tmp_path / "state.json").read_text())["steps"] == 256
    _, record = train(spec, None, tmp_path)
    assert record["resumed_from"] == 256 and record["steps"] == 768
    assert record["steps_run_now"] == 512
    assert [p.name for p in tmp_path.glob("*.zip")] == ["model_768.zip"]


@pytest.mark.parametrize(("args", "words"), [
    (["--policy", "bogus"], ["--policy", "bogus"]),
    (["--timesteps", "-5"], ["--timesteps"]),
    (["--checkpoint", "BAD"], ["--checkpoint"]),
])
def test_bad_input_is_one_line_exit_2(tmp_path, args, words):
    bad = tmp_path / "bad.pt"
    bad.write_bytes(b"not a checkpoint")
    args = [str(bad) if a == "BAD" else a for a in args]
    res = cli("experiment", "learned-tail", "--quick", *args, "--out", str(tmp_path / "o"))
    assert_clean_error(res, *words)
    assert not (tmp_path / "o").exists()


def test_the_spacing_shield_turns_a_far_tail_passive():
    """Beyond the limit the Tail's action is offset 0 (the chain's own rule closes the gap);
    inside it, the policy's action passes; no limit, no shield."""
    import numpy as np

    from macrostate_mj.tails.learned import shield

    obs = {"tail": np.zeros((10, 3)), "neighbour": np.zeros((10, 3))}
    obs["neighbour"][-1, :2] = (0.5, 0.2)               # 0.54 m away at the latest step
    action = np.array([0.1, -0.2], np.float32)
    assert np.array_equal(shield(obs, action, 0.6), action)
    assert np.array_equal(shield(obs, action, 0.5), np.zeros(2, np.float32))
    assert np.array_equal(shield(obs, action, None), action)


def test_the_srs_tail_acts_on_log_ticks_within_the_bounds():
    """SRS-Med's Tail asks its SR-phase policy once per log step and holds that offset,
    clipped to the action bounds."""
    import gymnasium

    import macrostate_mj  # noqa: F401
    from macrostate_mj.app.experiments.learned_tail.tail_eval import ENV_ID
    from macrostate_mj.tails.srs import SRSTail

    class Far:
        calls = 0

        def choose(self, sim):
            Far.calls += 1
            return np.array([5.0, -5.0])

    env = gymnasium.make(ENV_ID, time_limit=5.0, robots=3)
    obs, _ = env.reset(seed=3)
    every = env.unwrapped.task.every
    tail = SRSTail(env.unwrapped.task.sim, every, Far(), float(env.action_space.high[0]))
    for _ in range(3 * every):
        action = tail.act(obs, {})
        assert env.action_space.contains(action) and abs(action[0]) == env.action_space.high[0]
        obs, *_ = env.step(action)
    assert Far.calls == 3


def test_the_2x_heuristic_is_an_estimator_by_name_with_its_own_policy_folder(tmp_path):
    from estimators.retlo.heuristic import Heuristic2X
    from macrostate_mj.app.experiments.learned_tail import estimator_inputs
    from macrostate_mj.app.experiments.learned_tail.tail_eval import make_env
    from macrostate_mj.tails.ppo import PPOSpec, folder_for

    env = make_env("heuristic2x", 5.0)
    assert isinstance(env.unwrapped.task.localizer.module, Heuristic2X)
    spec = PPOSpec(timesteps=512)
    assert folder_for(tmp_path, spec, estimator_inputs("heuristic2x")) != folder_for(
        tmp_path, spec, estimator_inputs(None))
