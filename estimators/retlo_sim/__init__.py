"""ReTLo in simulation (dissertation §2.5): three chained small MLPs trained on 3-robot chains of
the robotarium scenario and applied modularly to longer chains (Fig 2.2).

frames.py (module frame, features), mlp.py (the networks), estimate.py (modular estimation and
errors). The MuJoCo runs live in `collectors.robotarium` and `collectors.robotarium_cases`, the
pipeline in `macrostate_mj.app.experiments.retlo_sim`: estimators work on arrays only.
"""
