"""The Tail's tasks by name, in one place (as dm_control's `suite`): `SUITE` (`env.task.TASKS`)
imports every task on first read, each registered by name where it is defined, and `load` builds
the task's `control.Environment` on a scenario's world.
"""

from __future__ import annotations

import numpy as np
from dm_control import mujoco as dm_mujoco
from dm_control.mujoco import wrapper
from dm_control.rl import control

from macrostate_mj.chain.scenarios import scenario_for
from macrostate_mj.chain.world import build_world, validate_chain
from macrostate_mj.core.errors import UserError
from macrostate_mj.env.task import TASKS, TailTask

SUITE = TASKS


def load(name: str = "explore", scenario: str = "lab", robots: int = 3, history: int = 10,
         observe: str = "truth", time_limit: float = 60.0,
         random: np.random.RandomState | int | None = None, **options) -> control.Environment:
    """The dm_control `Environment` of the task `name` (its task: `.task`, its simulation:
    `.task.sim`); `options` go to the task's `create` (`caging=CagingConfig(...)`)."""
    return environment(SUITE[name], scenario, robots, history, observe, time_limit, random,
                       **options)


def environment(task: type[TailTask], scenario: str = "lab", robots: int = 3, history: int = 10,
                observe: str = "truth", time_limit: float = 60.0,
                random: np.random.RandomState | int | None = None,
                **options) -> control.Environment:
    """`load` of a task class rather than a name: also the team tasks, which the Gymnasium view
    cannot wrap (`env.multi` does)."""
    if not (isinstance(time_limit, int | float) and 0 < time_limit < float("inf")):
        raise UserError(f"time_limit must be a positive finite number of seconds, got "
                        f"{time_limit!r}", "time_limit")
    cfg = scenario_for(scenario)
    validate_chain(cfg, robots, time_limit)
    world = build_world(cfg, robots)
    physics = dm_mujoco.Physics.from_model(wrapper.MjModel(world.model))
    made = task.create(world, physics.data.ptr, history, observe, random, **options)
    return control.Environment(physics, made, time_limit=time_limit,
                               control_timestep=1 / cfg.command_hz)
