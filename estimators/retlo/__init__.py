"""ReTLo (remote teammate localization, dissertation ch. 2-3): a 3-robot module, applied along
chains of any length, in both chapters' forms.

`frames` (the reference-robot frame and what a module sees in it), `chain` (the `Module`
protocol, the one chain step, offline inference), `online` (the same step live, as a Tail runs
it), `report` (errors and their reports), `heuristic` (the 2X heuristic), `mlp` (§2.5's three
chained MLPs), `models` and `train` (§2.6/§3.3's FC and LSTM modules, in torch), `heads`
(a point or a Gaussian position output), `gaussian` (calibration, mixtures, ellipses; numpy),
`propagate` (uncertainty carried along the chain), `mixture` (a deep ensemble of Gaussian
modules), `api` (fit and evaluate from ThymioLoc files or world arrays), `synthetic`
(chains with a known law).

One unit throughout: metres and radians, world x right, y up. Centimetres appear only at the
edges: ThymioLoc files (`api`), chapter 3's reports (cm, as its figures), and the networks'
inputs (`models`: they were designed and first trained in cm).
"""


from dataclasses import dataclass

from macrostate_mj.core.registry import Registry


@dataclass(frozen=True)
class ModelKind:
    """What a ReTLo network of a kind reads: the observation alone (§2.6.2.3's FC baseline) or
    also ℓ steps of history through an LSTM (§2.6)."""

    history: bool


# here, not in models: the CLI lists them without importing torch
MODEL_KINDS: Registry[ModelKind] = Registry("model kind")
MODEL_KINDS.register("fc")(ModelKind(history=False))
MODEL_KINDS.register("lstm")(ModelKind(history=True))
UNCERTAINTIES = ("none", "gaussian", "gaussian-faithful")   # `heads.HEADS`' names, likewise
CM_PER_M = 100.0
