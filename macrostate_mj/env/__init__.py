"""The Tail as an agent: dm_control tasks (`suite.SUITE`: `explore`, `caging`; `suite.load`
builds one's environment) and their Gymnasium view (`gym.TailEnv`).

Importing this package registers the Gymnasium ids (`gymnasium.make("macrostate_mj/
ExploreTail-v0")`), by entry point only: it imports nothing of the env itself. The testbed core
never imports it; it imports the core.
"""

import gymnasium

gymnasium.register(id="macrostate_mj/ExploreTail-v0", entry_point="macrostate_mj.env.gym:TailEnv",
                   kwargs={"task": "explore"})
gymnasium.register(id="macrostate_mj/CagingTail-v0", entry_point="macrostate_mj.env.gym:TailEnv",
                   kwargs={"task": "caging", "scenario": "robotarium", "robots": 6,
                           "time_limit": 90.0})
