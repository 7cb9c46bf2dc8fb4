"""The built-in scenarios, and how a command names a scenario: a built-in's name, a scenario
file's path, or an already resolved `ScenarioConfig` (what requests and workers carry).

The built-ins are scenario files shipped in the package (`assets/scenarios/*.toml`), loaded
once, like any user's file.
"""

from __future__ import annotations

from pathlib import Path

from macrostate_mj.chain.scenario import ScenarioConfig
from macrostate_mj.chain.scenario_file import builtin_names, is_file_ref, load_scenario

SCENARIOS: dict[str, ScenarioConfig] = {name: load_scenario(name) for name in builtin_names()}
ScenarioRef = str | Path | ScenarioConfig


def get_scenario(ref: ScenarioRef) -> ScenarioConfig:
    """A built-in by name, a scenario file by path, or `ref` itself when already resolved."""
    if isinstance(ref, ScenarioConfig):
        return ref
    if not is_file_ref(ref) and str(ref) in SCENARIOS:
        return SCENARIOS[str(ref)]
    return load_scenario(ref)


def scenario_for(ref: ScenarioRef, head_speed: float | None = None) -> ScenarioConfig:
    """A scenario, with a Head speed override applied (and checked, as the scenario checks
    its own)."""
    cfg = get_scenario(ref)
    if head_speed is not None:
        cfg = cfg.with_overrides(head_speed=head_speed)
    return cfg


class ResolvesScenario:
    """For a request or config dataclass with a `scenario` field: a built-in's name or a
    scenario file given there is resolved once, on construction, so that everything below
    takes the `ScenarioConfig` itself."""

    def __post_init__(self) -> None:
        object.__setattr__(self, "scenario", get_scenario(self.scenario))  # type: ignore[attr-defined]
