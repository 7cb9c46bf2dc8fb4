"""Physics health of a chain world: every robot finite, upright, on the floor, inside the walls
and outside the obstacles.

`PhysicsMonitor.check(data)` is cheap (a few numpy reductions over the robots' bodies), so the
simulation loop calls it after every stretch of physics steps; it also keeps the run's worst
figures (lift, tilt, penetration, MuJoCo warnings) for `macrostate-mj soak`.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field

import mujoco
import numpy as np

from macrostate_mj.chain.world import World
from macrostate_mj.core.errors import RunFailure


class Fault(enum.Enum):
    """What went wrong (`PhysicsFault.describe` words it)."""

    NAN = enum.auto()        # a non-finite state, or MuJoCo reset a diverged one
    TIP = enum.auto()        # tilted past `max_tilt_deg`
    LIFT = enum.auto()       # body above its rest height by more than `max_lift` (climbing)
    ESCAPE = enum.auto()     # centre outside the walls
    INTRUDE = enum.auto()    # centre inside an obstacle (through it: contacts failed)


@dataclass(frozen=True)
class HealthLimits:
    """A Thymio does not climb onto its neighbour: a body more than `max_lift` above its rest
    height shows climbing long before a 45 degree tip."""

    max_tilt_deg: float = 30.0
    max_lift: float = 0.005          # m above the rest height of the body frame


@dataclass(frozen=True)
class PhysicsFault:
    fault: Fault
    robot: str
    time: float
    value: float                     # tilt (deg), lift (mm), distance outside or in (mm);
    #                                  0 for NaN

    def describe(self) -> str:
        what = {Fault.NAN: "has a NaN state",
                Fault.TIP: f"tipped {self.value:.0f} deg",
                Fault.LIFT: f"lifted {self.value:.1f} mm off the floor (climbing)",
                Fault.ESCAPE: f"left the arena by {self.value:.0f} mm",
                Fault.INTRUDE: f"is {self.value:.0f} mm inside an obstacle"}[self.fault]
        return f"robot {self.robot} {what} at t={self.time:.3f} s"


class PhysicsError(RunFailure):
    """The physics left the valid regime; carries the fault, never silently logged."""

    def __init__(self, fault: PhysicsFault):
        super().__init__(fault.describe())
        self.fault = fault


@dataclass
class HealthStats:
    """Worst figures seen over a run (at the checks, not at every physics step)."""

    max_lift_mm: float = 0.0
    min_upright: float = 1.0         # min over robots and checks of the body z axis' z component
    max_penetration_mm: float = 0.0
    warnings: dict[str, int] = field(default_factory=dict)


WARNINGS = {name.removeprefix("mjWARN_"): int(w)
            for name, w in mujoco.mjtWarning.__members__.items() if name != "mjNWARNING"}


DIVERGED = [int(getattr(mujoco.mjtWarning, f"mjWARN_BAD{q}")) for q in ("QPOS", "QVEL", "QACC")]


class PhysicsMonitor:
    """Checks one MjData of a chain world against `limits`."""

    def __init__(self, world: World, limits: HealthLimits | None = None):
        model = world.model
        self.names = world.names
        self.limits = limits or HealthLimits()
        self.body = world.body
        self.rest_z = model.qpos0[world.qpos_adr + 2].copy()
        # Escaping is leaving the walls: an open floor (walls = None) has none to leave.
        self.half = (np.array(world.scenario.arena) / 2 if world.scenario.walls is not None
                     else np.full(2, np.inf))
        self.obstacles = world.scenario.obstacles
        self.min_up = float(np.cos(np.radians(self.limits.max_tilt_deg)))
        self.stats = HealthStats()
        # MuJoCo resets a diverged state itself (to qpos0, with a warning): that is a NaN too.
        root = model.body_rootid[model.dof_bodyid]
        self.dof_robot = np.array([int(np.flatnonzero(self.body == r)[0]) if r in self.body
                                   else -1 for r in root])

    def reset(self) -> None:
        """Forget the worst figures (a new episode)."""
        self.stats = HealthStats()

    def check(self, data: mujoco.MjData, t: float | None = None) -> PhysicsFault | None:
        """The first fault of this state (NaN, tip, lift, escape, intrusion) at time `t` (default
        `data.time`, which MuJoCo's own reset of a diverged state sets back to 0).

        It runs after every stretch of physics, so it is written for few numpy calls: a sum is
        finite exactly when every term is (MuJoCo resets a state long before one overflows)."""
        t = float(data.time) if t is None else t
        if not math.isfinite(float(data.qpos.sum()) + float(data.qvel.sum())):
            bad = ~np.isfinite(data.xpos[self.body]).all(axis=1)
            return PhysicsFault(Fault.NAN, self.names[int(np.argmax(bad))], t, 0.0)
        for w in DIVERGED:
            if data.warning[w].number:
                robot = self.dof_robot[min(data.warning[w].lastinfo, len(self.dof_robot) - 1)]
                name = self.names[robot] if robot >= 0 else "?"
                return PhysicsFault(Fault.NAN, name, t, 0.0)
        pos = data.xpos[self.body]
        up = data.xmat[self.body, 8]
        lift = pos[:, 2] - self.rest_z
        out = np.abs(pos[:, :2]) - self.half
        up_min, lift_max, out_max = float(up.min()), float(lift.max()), float(out.max())
        s = self.stats
        s.min_upright = min(s.min_upright, up_min)
        s.max_lift_mm = max(s.max_lift_mm, lift_max * 1000)
        if data.ncon:
            s.max_penetration_mm = max(s.max_penetration_mm,
                                       float(-data.contact.dist[:data.ncon].min()) * 1000)
        if up_min < self.min_up:
            i = int(np.argmin(up))
            return PhysicsFault(Fault.TIP, self.names[i], t,
                                float(np.degrees(np.arccos(np.clip(up[i], -1, 1)))))
        if lift_max > self.limits.max_lift:
            i = int(np.argmax(lift))
            return PhysicsFault(Fault.LIFT, self.names[i], t, float(lift[i]) * 1000)
        if out_max > 0:
            i = int(np.argmax(out.max(axis=1)))
            return PhysicsFault(Fault.ESCAPE, self.names[i], t, float(out[i].max()) * 1000)
        for ob in self.obstacles:
            depth = ob.depth(pos[:, :2])
            if depth.max() > 0:
                i = int(np.argmax(depth))
                return PhysicsFault(Fault.INTRUDE, self.names[i], t, float(depth[i]) * 1000)
        return None

    def record_warnings(self, data: mujoco.MjData) -> None:
        """MuJoCo's own warning counters (contact buffer full, bad qacc, ...) for the stats."""
        self.stats.warnings = {name: int(data.warning[i].number)
                               for name, i in WARNINGS.items() if data.warning[i].number}

