"""Several Tails in one team as a PettingZoo `ParallelEnv` (`parallel_env(**kwargs)`; needs the
`multi` extra): seed §5.2's "multiple Tail robots deployed in the same team to cooperatively
drive other robots to a destination state".

The team is a Head leading two chains (`chain.team`), not the one-chain caging team with a
second Tail beside it: a Tail in ReTLo is the far end of a chain from its Head, observing one
neighbour and moving the Followers of its chain through them; a second Tail in a line team would
have no chain of its own to drive. With two chains each Tail drives its own, and the two must
cooperate to reach the destination state (a ring round the object: task "caging",
`env.caging.TeamCagingTask`).

Agents "tail_0" (chain A, the longer) and "tail_1" (chain B) each observe what the one Tail of
`CagingTail-v0` does: their own and their neighbour's (history, 3) poses and `object`; each
acts with its destination offset (Box, ±2d). The reward, the ending and the info are the
team's, the same for both; both leave `agents` together at the episode's end. Seeding: one
generator from `reset(seed=...)` seeds the task, so a seed repeats an episode bit for bit.
"""

from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from pettingzoo import ParallelEnv

from macrostate_mj.chain.team import split_branches
from macrostate_mj.core.errors import UserError
from macrostate_mj.env.caging import TeamCagingTask
from macrostate_mj.env.suite import environment
from macrostate_mj.env.view import OverheadView

TASKS = {"caging": TeamCagingTask}


def parallel_env(**kwargs: Any) -> TeamEnv:
    """The team environment (see `TeamEnv` for the keyword arguments)."""
    return TeamEnv(**kwargs)


class TeamEnv(OverheadView, ParallelEnv):
    """Tails of one team as agents (see the module docstring). `environment` is the dm_control
    environment it steps, `task` its task (`task.sim` the `chain.team.BranchedSim`)."""

    metadata = {"name": "macrostate_mj_team_caging_v0", "render_modes": ["rgb_array"],
                "render_fps": 30, "is_parallelizable": True}

    def __init__(self, task: str = "caging", scenario: str = "robotarium", robots: int = 6,
                 tails: int = 2, history: int = 10, observe: str = "truth",
                 time_limit: float = 90.0, render_mode: str | None = None, **options: Any):
        if task not in TASKS:
            raise UserError(f"unknown team task {task!r}; choose one of {', '.join(TASKS)}",
                            "task")
        if render_mode not in (None, "rgb_array"):
            raise UserError(f"render_mode {render_mode!r}; only 'rgb_array' or None",
                            "render_mode")
        if isinstance(robots, int | np.integer) and not isinstance(robots, bool):
            split_branches(int(robots), tails)         # the counts, before building anything
        self.render_mode = render_mode
        self.environment = environment(TASKS[task], scenario, robots, history, observe,
                                       time_limit, tails=tails, **options)
        self.possible_agents = [f"tail_{i}" for i in range(tails)]
        self.agents: list[str] = []
        self.metadata = {**self.metadata, "render_fps": self.task.sim.cfg.command_hz}
        spec = self.environment.action_spec()
        bound = np.float32(spec.maximum.max())
        hx, hy = np.array(self.task.sim.cfg.arena) / 2         # walls bound every pose
        low, high = np.array([-hx, -hy, -np.pi]), np.array([hx, hy, np.pi])
        obs = {name: spaces.Box(np.broadcast_to(low, s.shape[1:]),
                                np.broadcast_to(high, s.shape[1:]), dtype=np.float64)
               for name, s in self.environment.observation_spec().items()}
        self._spaces = {a: (spaces.Dict(obs), spaces.Box(-bound, bound, (2,), np.float32))
                        for a in self.possible_agents}
        self._np_random: np.random.Generator | None = None
        self._renderer = None

    @property
    def task(self) -> TeamCagingTask:
        return self.environment.task

    def observation_space(self, agent: str) -> spaces.Dict:
        return self._spaces[agent][0]      # the same object each call, as PettingZoo asks

    def action_space(self, agent: str) -> spaces.Box:
        return self._spaces[agent][1]

    def reset(self, seed: int | None = None, options: dict | None = None
              ) -> tuple[dict[str, dict], dict[str, dict]]:
        if seed is not None or self._np_random is None:
            self._np_random, _ = seeding.np_random(seed)
        self.task.seed(int(self._np_random.integers(2**31)))
        step = self.environment.reset()
        self.agents = list(self.possible_agents)
        info = self.task.reset_info()
        return self._split(step.observation), {a: dict(info) for a in self.agents}

    def step(self, actions: dict[str, Any]) -> tuple[dict, dict, dict, dict, dict]:
        if not self.agents:
            raise gymnasium.error.ResetNeeded("the episode has ended: call reset()")
        missing = [a for a in self.agents if a not in actions]
        if missing:
            raise gymnasium.error.InvalidAction(f"no action for {', '.join(missing)}")
        for agent in self.agents:
            if not self.action_space(agent).contains(np.asarray(actions[agent], np.float32)):
                raise gymnasium.error.InvalidAction(
                    f"{agent}'s action {np.asarray(actions[agent]).tolist()} is outside "
                    f"{self.action_space(agent)}")
        step = self.environment.step(np.array([actions[a] for a in self.possible_agents],
                                                        np.float64))
        terminated = step.last() and step.discount == 0.0
        truncated = step.last() and not terminated
        info = self.task.step_info()
        agents = self.agents
        if step.last():
            self.agents = []
        return (self._split(step.observation), dict.fromkeys(agents, float(step.reward)),
                dict.fromkeys(agents, bool(terminated)), dict.fromkeys(agents, bool(truncated)),
                {a: dict(info) for a in agents})

    def _split(self, observation: dict) -> dict[str, dict]:
        """Each agent's row of the team's observation."""
        return {a: {k: np.asarray(v[i], np.float64) for k, v in observation.items()}
                for i, a in enumerate(self.possible_agents)}
