"""The Tail as an agent: dm_control tasks (`suite.SUITE`: `explore`, `caging`, `localize`;
`suite.load` builds one's environment) and their Gymnasium view (`gym.TailEnv`).

The Gymnasium ids (`macrostate_mj/ExploreTail-v0`, `macrostate_mj/CagingTail-v0`,
`macrostate_mj/LocalizeTail-v0`) are registered by `import macrostate_mj` itself
(`macrostate_mj.gym_ids`), so `gymnasium.make("macrostate_mj:macrostate_mj/ExploreTail-v0")`
needs no import of this package. The testbed core never imports it; it imports the core.
Several Tails of one team are a PettingZoo `ParallelEnv` (`env.multi.parallel_env`, the `multi`
extra); nothing else here imports PettingZoo.
"""
