"""The Gymnasium ids of the Tail environments: the one place they and their defaults are set.

`import macrostate_mj` registers them, so `gymnasium.make("macrostate_mj:macrostate_mj/
ExploreTail-v0")` works in a fresh process: gymnasium imports the module named before the colon,
then looks the id up (stable-baselines3's `make_vec_env` workers rely on that). The entry points
are strings, so registering imports nothing of `macrostate_mj.env` (dm_control, the physics):
only gymnasium itself, and not even that is required for the rest of the package to import.

`ENVS` is written here rather than derived from the task registry (`env.task.TASKS`): reading
that registry imports the tasks (dm_control, the physics), which `import macrostate_mj` must not,
and an id is more than a task's name (its defaults, for LocalizeTail another entry point). Each
id's task is one of `TASKS` (`tests/core/test_registry.py` checks).
"""

from __future__ import annotations

from typing import Any

ENTRY_POINT = "macrostate_mj.env.gym:TailEnv"
ENVS: dict[str, dict[str, Any]] = {
    "macrostate_mj/ExploreTail-v0": {"task": "explore"},
    "macrostate_mj/CagingTail-v0": {"task": "caging", "scenario": "robotarium", "robots": 6,
                                    "time_limit": 90.0},
    "macrostate_mj/LocalizeTail-v0": {"scenario": "webots", "robots": 5},
}
# An id made by another factory than `ENTRY_POINT` (one that needs an estimator).
ENTRY_POINTS = {"macrostate_mj/LocalizeTail-v0": "macrostate_mj.env.estimated:localize_tail"}


def register() -> bool:
    """Register every id not yet registered; False, registering nothing, without gymnasium."""
    try:
        import gymnasium
    except ImportError:
        return False
    for env_id, kwargs in ENVS.items():
        if env_id not in gymnasium.registry:    # a re-import would warn of overriding it
            gymnasium.register(id=env_id, entry_point=ENTRY_POINTS.get(env_id, ENTRY_POINT),
                               kwargs=dict(kwargs))
    return True
