"""Domain randomization (MuJoCo Playground keeps it in `randomize.py`): per episode, physics,
controller and imaging parameters drawn from ranges around the scenario's values.

A profile maps parameter names to (low, high) factors applied to the scenario's own value, so one
profile serves every scenario: `k_f: (0.8, 1.2)` multiplies the Follower gain by a uniform draw in
[0.8, 1.2]. The `ABSOLUTE` parameters, whose scenario value is zero by default, are added in
their own unit instead (`frame_jitter: (0, 0.1)` delays each frame by up to 0-0.1 s more,
`frame_alternation: 0.05` takes every other row's frames 0.05 s earlier,
`follow_start: 0.01` lets a rear robot wait 1 cm more before it sets off, `follow_hold: 0.3`
makes one that is nearer the robot ahead than 0.3 m closer than d stop rather than back off,
`head_turn_speed: 1` drives the Head through its turns at full speed); `max_turn: 0.5` halves
the turn a Psi Head may take toward its next waypoint (a factor, capped at 180 degrees).
Draws come from the episode's own stream (`EpisodeSpec.rng(3)`), so a randomized collection is
still bit-identical for any worker count. A profile is a built-in name or a JSON
file `{"k_f": [0.8, 1.2], ...}`; a bare number fixes a factor (`{"k_f": 1.1}`: what
`sysid` writes). The collection's manifest records it.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, fields, replace
from pathlib import Path

import numpy as np

from macrostate_mj.chain.motion import WaitForBehind
from macrostate_mj.chain.scenario import ScenarioConfig
from macrostate_mj.chain.world import World
from macrostate_mj.core.errors import UserError
from macrostate_mj.vision.imaging import NoiseConfig

# Where each parameter lives: the scenario's rules, the compiled model, or the imaging chain.
SCENARIO = ("k_f", "k_t", "k_omega", "head_speed", "chain_speed", "marker_jitter",
            "head_jitter_scale")
RULES = ("wait_slack", "follow_start", "follow_hold")   # the lab rule (`WaitForBehind`)
MODEL = ("wheel_friction", "motor_torque")
IMAGING = ("sensor_sigma", "blur_px", "psf_sigma_px")
TIMING = ("frame_hz", "frame_jitter", "frame_alternation")  # the camera's frames (`camera_hz`)
SPREAD = ("wheel_spread", "marker_offset")   # how the robots differ (`ScenarioConfig`)
HEAD = ("head_turn_speed", "max_turn")      # how the Head drives: through turns, and how far
#                                             it turns for its next waypoint (a Psi planner)
PARAMETERS = (*SCENARIO, *RULES, *MODEL, *IMAGING, *TIMING, *SPREAD, *HEAD)
# added in their unit (s, m, a share), not factors: zero by default; `ADDED` the scenario's
# own fields among them (the rest live in the frame timing and the follower rule)
ADDED = (*SPREAD, "head_turn_speed")
ABSOLUTE = ("frame_jitter", "frame_alternation", "follow_start", "follow_hold", *ADDED)

# ±20 % on the motion rules and speeds, ±30 % on wheel grip and motor torque, the imaging noise
# from half to twice its default, the marker jitter over the span the 1-D scan of `sysid` found
# flat (docs): wide enough to cover the lab-vs-real gaps measured by `stats --compare` (speed,
# turn rate and jitter distributions).
WIDE = {"k_f": (0.8, 1.2), "k_t": (0.8, 1.2), "k_omega": (0.8, 1.2),
        "head_speed": (0.8, 1.2), "chain_speed": (0.8, 1.2), "marker_jitter": (0.7, 1.4),
        "wheel_friction": (0.7, 1.3), "motor_torque": (0.7, 1.3),
        "sensor_sigma": (0.5, 2.0), "blur_px": (0.5, 2.0), "psf_sigma_px": (0.5, 2.0)}

# A profile maps a parameter to its (low, high) factors or to one fixed factor.
PROFILES: dict[str, dict[str, tuple[float, float] | float]] = {
    "wide": WIDE,
    # `wide`, with the Head's and chain's speed caps, the Tail gain and the wait rule's slack
    # reaching up to where the first `sysid` fit went (faster, tighter, more patient): the
    # best sim-to-real transfer measured (docs: reproduction/sim-to-real).
    "wider": {**WIDE, "k_f": (0.8, 1.3), "k_t": (0.8, 1.6), "head_speed": (0.8, 1.6),
              "chain_speed": (0.8, 1.5), "wait_slack": (0.7, 1.5)},
}
# `wider`, with a Head that keeps half to all of its speed through its turns and turns at
# most 72-180 degrees for its next waypoint (a Psi lab): the real Head's steady speed and the
# real chains that never fold (docs: decisions/sysid).
PROFILES["wider-head"] = {**PROFILES["wider"], "head_turn_speed": (0.5, 1.0),
                          "max_turn": (0.4, 1.0)}
# `wider-head`, with rear robots that stop and go like the real ones: stiff gains (Follower
# 1.5-5x, Tail 1-2x) capped near the Head's speed (0.45-1x the chain's), stopping rather than
# backing off when close (`follow_hold` = the spacing); `-slow` also draws the Head's speed
# nearer the real Head's (docs: reproduction/sim-to-real).
PROFILES["wider-rear"] = {**PROFILES["wider-head"], "k_f": (1.5, 5.0), "k_t": (1.0, 2.0),
                          "chain_speed": (0.45, 1.0), "follow_hold": 0.3}
PROFILES["wider-rear-slow"] = {**PROFILES["wider-rear"], "head_speed": (0.75, 1.15)}
PROFILES["wider-head-slow"] = {**PROFILES["wider-head"], "head_speed": (0.75, 1.15)}
# The `lab` refit (`sysid`, results/sysid_refit): stiff rear robots capped near the Head's speed,
# a quieter Head marker. Not the lab's defaults, since with these gains a parked rear robot turns
# on the spot at the smallest pull (docs: decisions/sysid); `refit` fixes the factors,
# `refit-wider` draws `wider`'s ranges around them (each range times the fitted factor).
REFIT = {"k_f": 4.8917, "k_t": 1.8631, "k_omega": 1.0835, "head_speed": 0.9504,
         "chain_speed": 0.4807, "wait_slack": 1.4125, "marker_jitter": 1.0066,
         "head_jitter_scale": 0.7382}


def around(factors: dict[str, float], ranges: dict[str, tuple[float, float] | float] | None
           ) -> dict[str, tuple[float, float] | float]:
    """A profile centred on fitted `factors`: each range of `ranges` times the parameter's
    fitted factor (1 where none was fitted; an `ABSOLUTE` one's range shifted by its fitted
    value), the other fitted factors fixed."""
    out: dict[str, tuple[float, float] | float] = dict(factors)
    for name, bounds in (ranges or {}).items():
        low, high = bounds if isinstance(bounds, tuple | list) else (bounds, bounds)
        if name in ABSOLUTE:
            f = factors.get(name, 0.0)
            low, high = low + f, high + f
        else:
            f = factors.get(name, 1.0)
            low, high = low * f, high * f
        out[name] = (low, high) if low != high else low
    return out


PROFILES["refit"] = dict(REFIT)
PROFILES["refit-wider"] = around(REFIT, PROFILES["wider"])
# `wider-rear` with the rows' shared timing (every other row's frames 0.03 s earlier) and the
# Head's share of the marker jitter that goes with it, as `sysid --only frame_alternation --only
# head_jitter_scale --base wider-rear` fitted them on the real Train file alone
# (results/sysid_timing2): the sim-to-real recipe (docs: reproduction/sim-to-real).
TIMED = {"frame_alternation": 0.0303, "head_jitter_scale": 0.6274}
PROFILES["wider-rear-timed"] = around(TIMED, PROFILES["wider-rear"])


@dataclass(frozen=True)
class Randomization:
    """A named profile: parameter -> (low, high) factor."""

    name: str
    ranges: tuple[tuple[str, float, float], ...]

    @classmethod
    def parse(cls, profile: str) -> Randomization:
        """A built-in profile's name or a JSON file's path; one-line errors for anything else."""
        if profile in PROFILES:
            ranges = PROFILES[profile]
        else:
            path = Path(profile)
            if not path.is_file():
                raise UserError(f"--randomize {profile!r} is neither a profile "
                                f"({', '.join(PROFILES)}) nor a JSON file of ranges")
            try:
                ranges = json.loads(path.read_text())
            except ValueError as err:                # bad JSON, or not text at all
                raise UserError(f"--randomize {path}: not a JSON object of ranges ({err}); "
                                "write {\"k_f\": [0.8, 1.2], ...}") from None
            if not isinstance(ranges, dict) or not ranges:
                raise UserError(f"--randomize {path}: want a non-empty object of parameter: "
                                "[low, high] factors")
        out = []
        for name, bounds in ranges.items():
            if name not in PARAMETERS:
                raise UserError(f"--randomize: unknown parameter {name!r}; choose from "
                                f"{', '.join(PARAMETERS)}")
            fixed = isinstance(bounds, int | float) and not isinstance(bounds, bool)
            try:
                low, high = (float(bounds),) * 2 if fixed else (float(b) for b in bounds)
            except (TypeError, ValueError):
                raise UserError(f"--randomize: {name} wants [low, high] factors or one fixed "
                                f"factor, got {bounds!r}") from None
            least = 0.0 if name in ABSOLUTE else math.ulp(0.0)
            if not (math.isfinite(low) and math.isfinite(high)) or low < least or \
                    (low >= high and not fixed):
                what = ("values (s, m) with 0 <= low < high" if name in ABSOLUTE
                        else "positive factors with 0 < low < high")
                raise UserError(f"--randomize: {name} range [{low:g}, {high:g}] is empty or "
                                f"out of range; give {what}")
            out.append((name, low, high))
        return cls(profile if profile in PROFILES else str(Path(profile).resolve()),
                   tuple(sorted(out)))

    def identity(self) -> dict:
        """What data drawn from it depend on: its ranges, not its name (a file's path), so a
        copy of the profile elsewhere draws the same episodes and resumes the same collection."""
        return {"ranges": self.ranges}

    def profile(self) -> dict[str, tuple[float, float] | float]:
        """Its ranges as a profile (what `around` centres on a fit)."""
        return {name: low if low == high else (low, high) for name, low, high in self.ranges}

    def draw(self, rng: np.random.Generator) -> dict[str, float]:
        """One episode's factors, in the profile's (sorted) order."""
        return {name: low if low == high else float(rng.uniform(low, high))
                for name, low, high in self.ranges}


def check_fits(profile: Randomization, cfg: ScenarioConfig) -> None:
    """Refuse, before any episode, a profile whose extremes make no valid scenario (a frame
    jitter as long as the fastest frame period)."""
    highest = {name: high for name, _, high in profile.ranges}
    try:
        randomized_scenario(cfg, highest)
    except UserError as err:
        raise UserError(f"--randomize {profile.name}: at its highest values, {err}") from None


def randomized_scenario(cfg: ScenarioConfig, factors: dict[str, float]) -> ScenarioConfig:
    cfg = replace(cfg, **{k: getattr(cfg, k) * f for k, f in factors.items() if k in SCENARIO})
    cfg = replace(cfg, **{k: getattr(cfg, k) + f for k, f in factors.items() if k in ADDED})
    if "max_turn" in factors:
        if not hasattr(cfg.planner, "max_turn"):
            raise UserError(f"--randomize: max_turn turns a Psi Head's waypoints; {cfg.name}'s "
                            f"planner is {type(cfg.planner).__name__}: leave max_turn out")
        cfg = replace(cfg, planner=replace(
            cfg.planner, max_turn=min(180.0, cfg.planner.max_turn * factors["max_turn"])))
    if set(TIMING) & set(factors):
        cfg = replace(cfg, frame_hz=cfg.camera_hz * factors.get("frame_hz", 1.0),
                      frame_jitter=cfg.frame_jitter + factors.get("frame_jitter", 0.0),
                      frame_alternation=cfg.frame_alternation
                      + factors.get("frame_alternation", 0.0))
    rule = cfg.followers
    if isinstance(rule, WaitForBehind) and set(RULES) & set(factors):
        cfg = replace(cfg, followers=replace(
            rule, slack=rule.slack * factors.get("wait_slack", 1.0),
            start=rule.start + factors.get("follow_start", 0.0),
            hold=rule.hold + factors.get("follow_hold", 0.0)))
    return cfg


def randomized_noise(noise: NoiseConfig, factors: dict[str, float]) -> NoiseConfig:
    names = {f.name for f in fields(NoiseConfig)}
    return replace(noise, **{k: getattr(noise, k) * f for k, f in factors.items()
                             if k in IMAGING and k in names})


def randomize_model(world: World, factors: dict[str, float]) -> None:
    """Scale the compiled model's wheel friction and motor torque limits in place."""
    model = world.model
    if "wheel_friction" in factors:
        wheels = [model.geom(f"{n}/wheel_{side}").id for n in world.names
                  for side in ("left", "right")]
        model.geom_friction[wheels, 0] *= factors["wheel_friction"]
    if "motor_torque" in factors:
        motors = [*world.ctrl_left, *world.ctrl_right]
        model.actuator_forcerange[motors] *= factors["motor_torque"]
