"""ReTLo (remote teammate localization, dissertation ch. 2-3): a 3-robot module, applied along
chains of any length.

`frames` (the reference-robot frame and module inputs), `models` (2X heuristic, FC, LSTM),
`chain` (modular inference and its errors), `train` (training, checkpoints), `synthetic`
(chains with a known law for tests and benchmarks). Fig 2.7-2.9 are drawn by
`macrostate_mj.app.experiments.retlo`.
"""

MODEL_KINDS = ("fc", "lstm")   # here, not in models: the CLI lists them without importing torch
