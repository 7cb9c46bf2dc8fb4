"""A scenario as one typed, frozen config: what a scenario file (`chain.scenario_file`) or a
built-in (`chain.scenarios`) resolves into, and what every request and worker carries.

A scenario describes its arena scene too (`arena`, `walls`, `camera`, `look`, `physics`: the
plain dataclasses of `chain.scene`, from which `scene.build_scene` generates the MJCF). Robot
geometry (wheel radius, track, top speed) is not repeated here: it is read from the robot's
compiled MJCF, so its XML stays the single source of truth.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from macrostate_mj.chain.motion import FollowerRule
from macrostate_mj.chain.planners import PlannerSpec
from macrostate_mj.chain.scene import Camera, Look, Obstacle, Physics, Walls, check_camera
from macrostate_mj.core.errors import UserError


def steps_per_tick(period: float, dt: float, what: str) -> int:
    """Whole physics steps per tick, or a clear error (dm_control's divisibility check): a rate
    that is not a whole number of steps makes its ticks jitter between two step counts."""
    steps = period / dt
    if abs(steps - round(steps)) > 1e-6 or round(steps) < 1:
        raise UserError(f"{what} period {period:g} s is {steps:.3f} physics steps of {dt:g} s; "
                        "choose a rate or timestep that divides into whole steps")
    return int(round(steps))


@dataclass(frozen=True)
class ScenarioConfig:
    name: str
    robot: str                      # macrostate_mj/assets/mjcf/<robot>/robot.xml
    arena: tuple[float, float]      # floor size (x, y) in metres, walls on its edges
    camera: Camera                  # the overhead camera (height, resolution, fovy)
    physics: Physics                # timestep (dividing both rates), integrator, ...
    spacing: float                  # follow distance d (m)
    k_f: float                      # Follower gain (1 / (m s))
    k_t: float                      # Tail gain
    k_omega: float                  # heading gain of the unicycle tracker (1 / s)
    head_speed: float               # Head's speed cap (m/s)
    chain_speed: float              # Followers' and Tail's speed cap (m/s)
    command_hz: float               # control / tracking rate
    log_hz: float                   # pose log rate (not synchronized with commands)
    planner: PlannerSpec            # the Head's planner: PsiGrid, CellWalk or PresetTwists
    followers: FollowerRule         # TwoNeighbours (§2.3) or WaitForBehind (lab, §2.6.2.1)
    allow_reverse: bool             # False: followers stop instead of backing up
    wall_margin: float              # keep waypoints and start poses this far from walls (m)
    reach_radius: float = 0.06      # Head has reached its waypoint within this distance (m)
    avoid_radius: float = 0.2       # robots repel each other within this distance (m)
    avoid_gain: float = 0.15        # repulsion speed at contact (m/s)
    marker_jitter: float = 0.0      # tracker position noise per frame, beyond what the
    #                                 imaging chain makes (sigma, m): see `CameraChain`
    walls: Walls | None = Walls()   # None: an open floor
    look: Look = Look()             # colours and lighting
    obstacles: tuple[Obstacle, ...] = ()    # static boxes and cylinders on the floor

    def __post_init__(self) -> None:
        """Refuse, when the scenario is made, rates that are not whole physics steps and a
        camera that does not see the whole arena."""
        check_camera(self.name, self.arena, self.camera)
        self._check_numbers()
        for i, ob in enumerate(self.obstacles):
            problem = ob.problem(self.arena)
            if problem is not None:
                raise UserError(f"{self.name}: arena.obstacles[{i}] {problem}")
        for what, hz in (("command", self.command_hz), ("log", self.log_hz)):
            if not hz > 0:
                raise UserError(f"{self.name}: the {what} rate must be positive, got {hz:g} Hz")
            steps_per_tick(1 / hz, self.physics.timestep, f"{self.name} {what}")

    def _check_numbers(self) -> None:
        """NaN, infinite, zero or negative sizes, gains and speeds are refused here, so the
        Python API refuses what the CLI does (a chain with k_f = nan never moves)."""
        named = {"arena": self.arena, "spacing": self.spacing, "k_f": self.k_f, "k_t": self.k_t,
                 "k_omega": self.k_omega, "head_speed": self.head_speed,
                 "chain_speed": self.chain_speed, "reach_radius": self.reach_radius,
                 "avoid_radius": self.avoid_radius, "timestep": self.physics.timestep}
        for key, value in named.items():
            for v in (value if isinstance(value, tuple) else (value,)):
                if not (isinstance(v, int | float) and math.isfinite(v) and v > 0):
                    raise UserError(f"{self.name}: {key} must be a positive finite number, "
                                    f"got {value!r}")
        for key, v in {"wall_margin": self.wall_margin, "avoid_gain": self.avoid_gain,
                       "marker_jitter": self.marker_jitter}.items():
            if not (math.isfinite(v) and v >= 0):
                raise UserError(f"{self.name}: {key} must be a non-negative finite number, "
                                f"got {v!r}")

    def with_overrides(self, **kw: object) -> ScenarioConfig:
        return replace(self, **kw)


# The three built-in scenes' fovy are the hand-written XMLs' 2 atan(half-extent / height),
# rounded to 0.01 deg (kept so renders and tracked poses stay bit for bit; within 0.04 px of
# framing the arena exactly).
