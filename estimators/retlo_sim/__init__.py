"""ReTLo in simulation (dissertation §2.5): three chained small MLPs trained on 3-robot chains of
the robotarium scenario and applied modularly to longer chains (Fig 2.2).

frames.py (module frame, features), data.py (treatments and test runs in MuJoCo), mlp.py (the
networks), estimate.py (modular estimation and errors), cases.py (Fig 2.2 cases),
experiment.py (the `experiment retlo-sim` pipeline).
"""
