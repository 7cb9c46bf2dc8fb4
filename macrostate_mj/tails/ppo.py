"""PPO on `LocalizeTail-v0` with a frozen estimator, checkpointed so a killed run resumes (for
`experiment learned-tail`).

stable-baselines3 is the `rl` extra: it is imported here only, when training starts. The model
and the step count it reached are saved together every `save_every` steps (the zip first, then
`state.json` naming it, each written atomically), so a rerun continues from the last save. A
resumed run is reproducible from that save, not bit-identical to an uninterrupted one (the
environments restart from fresh seeds, derived from the step count).

Training only: a chain break ends an episode, and the reward (minus the Head error, m, per
step) is negative, so ending early would pay. `training_env` charges `break_penalty` m for every
step the broken episode did not run; evaluation reports the raw error and the breaks apart.
The policy acts through the spacing shield (`learned.shield`, `shield_spacings` × the chain's
spacing) in training as at evaluation, so it learns what the shield lets it do. The environment
is named by its Gymnasium id; the frozen estimator it runs is the caller's (`checkpoint`, and
`estimator` the bytes or name that identify it in the checkpoint folder's key).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from macrostate_mj.core.cache import task_key
from macrostate_mj.core.errors import UserError
from macrostate_mj.core.io import write_json_atomic

TRAIN_SEEDS = 1000        # every training environment's seed is at least this (eval: 0..19)
STATE = "state.json"


@dataclass(frozen=True)
class PPOSpec:
    """Everything the trained policy depends on (its checkpoint folder's key)."""

    timesteps: int
    envs: int = 4
    n_steps: int = 256            # per env per rollout
    batch_size: int = 128
    n_epochs: int = 10
    learning_rate: float = 3e-4
    gamma: float = 0.99
    net: tuple[int, ...] = (64, 64)
    log_std_init: float = -2.0    # exploration σ ≈ 0.14 m (SB3's σ = 1 would clip every
                                  # action to the ±0.3 m bounds)
    save_every: int = 10_240
    break_penalty: float = 2.0    # m per step a broken episode did not run
    shield_spacings: float | None = 2.0   # passive beyond this gap to the neighbour (× d);
                                          # a break is at 2.5 d (chain.sim.BREAK_SPACINGS)
    time_limit: float = 60.0
    seed: int = 0


def require_sb3() -> Any:
    try:
        import stable_baselines3
    except ImportError:
        raise UserError("experiment learned-tail needs stable-baselines3: install the `rl` extra "
                        "(pip install 'macrostate-mj[rl]')") from None
    return stable_baselines3


def folder_for(root: Path, spec: PPOSpec, estimator: list) -> Path:
    """The policy's checkpoint folder, keyed by `spec` and the frozen estimator (`estimator`:
    its file, or the bytes of its name; empty for the env's default)."""
    # version 2: the estimator is given the first ℓ log steps (env.localize), scored after
    return root / task_key("learned-tail-ppo", 2, asdict(spec), estimator)[:16]


def training_env(env: Any, penalty: float, time_limit: float, shield_spacings: float | None
                 ) -> Any:
    """`env` wrapped to act through the spacing shield and to charge `penalty` m per step left
    when a chain break ends an episode (gymnasium is imported here, lazily, as the rest of the
    extra)."""
    import gymnasium

    from macrostate_mj.chain.sim import chain_broken
    from macrostate_mj.tails.learned import shield, shield_limit

    class Training(gymnasium.Wrapper):
        steps = 0
        obs: Any = None

        def reset(self, **kw: Any) -> tuple:
            self.steps = 0
            self.obs, info = self.env.reset(**kw)
            return self.obs, info

        def step(self, action: Any) -> tuple:
            sim = self.env.unwrapped.task.sim
            obs, reward, terminated, truncated, info = self.env.step(
                shield(self.obs, np.asarray(action), shield_limit(self.env, shield_spacings)))
            self.obs = obs
            self.steps += 1
            if terminated and info.get("fault") is None and chain_broken(sim):
                left = max(0, int(round(time_limit * sim.cfg.command_hz)) - self.steps)
                reward = float(reward) - penalty * left
                info = {**info, "chain_break": True}
            return obs, reward, terminated, truncated, info

    return Training(env)


def train(spec: PPOSpec, checkpoint: str | None, folder: Path, workers: int = 1,
          report: Callable[[int, int], None] = lambda done, total: None) -> tuple[Any, dict]:
    """The policy trained to `spec.timesteps` (resumed from `folder`'s last save, or loaded
    as it is when it got there before) and the training record: learning curve, steps run now."""
    sb3 = require_sb3()
    import torch
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

    folder.mkdir(parents=True, exist_ok=True)
    state = _read_state(folder)
    start = state["steps"] if state else 0
    torch.set_num_threads(1)
    if state and start >= spec.timesteps:
        model = sb3.PPO.load(folder / state["model"], device="cpu")
        return model, {**state, "resumed_from": start, "steps_run_now": 0}
    base = TRAIN_SEEDS + (spec.seed * 100_003 + start) % 2**30
    venv = make_vec_env(
        "macrostate_mj:macrostate_mj/LocalizeTail-v0", spec.envs, seed=base,
        env_kwargs={"checkpoint": checkpoint, "time_limit": spec.time_limit},
        wrapper_class=training_env,
        wrapper_kwargs={"penalty": spec.break_penalty, "time_limit": spec.time_limit,
                        "shield_spacings": spec.shield_spacings},
        vec_env_cls=SubprocVecEnv if workers > 1 else DummyVecEnv)
    if state:
        model = sb3.PPO.load(folder / state["model"], env=venv, device="cpu")
        model.set_random_seed(base)
    else:
        model = sb3.PPO("MultiInputPolicy", venv, n_steps=spec.n_steps,
                        batch_size=spec.batch_size, n_epochs=spec.n_epochs,
                        learning_rate=spec.learning_rate, gamma=spec.gamma, seed=base,
                        policy_kwargs={"net_arch": list(spec.net),
                                       "log_std_init": spec.log_std_init}, device="cpu", verbose=0)
    curve: list[dict] = list(state["curve"]) if state else []

    class Record(BaseCallback):
        """Per rollout: the finished episodes' raw return (minus the summed Head error) and
        breaks; a save every `save_every` steps."""

        def __init__(self) -> None:
            super().__init__()
            self.returns: list[float] = []
            self.lengths: list[int] = []
            self.breaks = 0
            self.saved = start

        def _on_step(self) -> bool:
            for done, info in zip(self.locals["dones"], self.locals["infos"], strict=True):
                if done and "episode" in info:
                    self.returns.append(float(info["episode"]["r"]))
                    self.lengths.append(int(info["episode"]["l"]))
                    self.breaks += bool(info.get("chain_break"))
            return True

        def _on_rollout_end(self) -> None:
            steps = int(self.num_timesteps)
            if self.returns:
                curve.append({"timesteps": steps, "episodes": len(self.returns),
                              "mean_return": float(np.mean(self.returns)),
                              "mean_length": float(np.mean(self.lengths)),
                              "breaks": self.breaks})
            self.returns, self.lengths, self.breaks = [], [], 0
            report(steps, spec.timesteps)
            if steps - self.saved >= spec.save_every:
                _save(self.model, folder, steps, curve)
                self.saved = steps

    model.learn(spec.timesteps - start, callback=Record(), reset_num_timesteps=not state)
    steps = int(model.num_timesteps)
    _save(model, folder, steps, curve)
    venv.close()
    return model, {"steps": steps, "curve": curve, "resumed_from": start,
                   "steps_run_now": steps - start}


def _read_state(folder: Path) -> dict | None:
    import json

    path = folder / STATE
    if not path.exists():
        return None
    state = json.loads(path.read_text())
    return state if (folder / state["model"]).exists() else None


def _save(model: Any, folder: Path, steps: int, curve: list[dict]) -> None:
    """The model as model_<steps>.zip, then state.json naming it; older zips removed."""
    name = f"model_{steps}.zip"
    part = folder / f".{name}.part"
    with open(part, "wb") as f:
        model.save(f)
    os.replace(part, folder / name)
    write_json_atomic(folder / STATE, {"steps": steps, "model": name, "curve": curve})
    for old in folder.glob("model_*.zip"):
        if old.name != name:
            old.unlink()
