"""The code behind each command, one module per command (group): the command (`app.cli`) only
parses flags and prints; the use case checks what the flags cannot, opens the run in its
output folder (`core.run.Run`: a manifest beside the outputs) and returns what is printed.

`simulate` and `export-mjcf` (`simulate`), `track` (`track`), `soak` (`soak`), `stats`
(`stats`), `sysid` (`sysid`), `flow`, `oc train` and `oc evaluate` (`oneclass`), `train retlo`
and `calibrate retlo` (`retlo_train`) and `evaluate retlo` (`retlo_eval`). `collect` is the one
command whose use case lives below the app (`collectors.runner.collect`): the experiments and
the SRS collection call it too. Each use case's tables (what the docs show of its outputs) sit
beside it, in the one registry of results sources.
"""
