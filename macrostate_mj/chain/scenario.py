"""A scenario as one typed, frozen config: what a scenario file (`chain.scenario_file`) or a
built-in (`chain.scenarios`) resolves into, and what every request and worker carries.

A scenario describes its arena scene too (`arena`, `walls`, `camera`, `look`, `physics`: the
plain dataclasses of `chain.scene`, from which `scene.build_scene` generates the MJCF). Robot
geometry (wheel radius, track, top speed) is not repeated here: it is read from the robot's
compiled MJCF, so its XML stays the single source of truth.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace

from macrostate_mj.chain.markers import ColourMarkers
from macrostate_mj.chain.motion import FollowerRule
from macrostate_mj.chain.noise import NoiseConfig
from macrostate_mj.chain.planners import PlannerSpec
from macrostate_mj.chain.robot import top_speed
from macrostate_mj.chain.scene import Camera, Look, Obstacle, Physics, Walls, check_camera
from macrostate_mj.chain.tags import ArucoMarkers
from macrostate_mj.chain.tracking import TrackingLimits
from macrostate_mj.core.errors import UserError

# A scenario file's tables and keys -> ScenarioConfig's fields: one home, read by the file
# loader (`chain.scenario_file`), written back by `scenario show`, and used here so that an
# error names both the field a Python caller set and the key a file sets.
LAYOUT: dict[str, dict[str, str]] = {
    "": {"name": "name"},
    "arena": {"size": "arena", "margin": "wall_margin", "obstacles": "obstacles"},
    "robot": {"model": "robot", "wheel_spread": "wheel_spread"},
    "chain": {"spacing": "spacing", "head_speed": "head_speed", "chain_speed": "chain_speed",
              "k_f": "k_f", "k_t": "k_t", "k_omega": "k_omega", "allow_reverse": "allow_reverse",
              "reach_radius": "reach_radius", "avoid_radius": "avoid_radius",
              "avoid_gain": "avoid_gain", "head_turn_speed": "head_turn_speed"},
    "rates": {"command_hz": "command_hz", "log_hz": "log_hz", "frame_hz": "frame_hz",
              "frame_jitter": "frame_jitter", "frame_alternation": "frame_alternation"},
    "noise": {"marker_jitter": "marker_jitter", "head_jitter_scale": "head_jitter_scale",
              "marker_offset": "marker_offset"},
}
NESTED = {"camera": "camera", "physics": "physics", "look": "look",
          "tracking": "tracking"}   # table -> dataclass field
SHARED = {"imaging": "noise"}   # a dataclass field whose keys share a table with flat fields


def file_key(field_name: str) -> str:
    """The scenario file's key for a config field (`spacing` -> `chain.spacing`)."""
    for section, keys in LAYOUT.items():
        for key, name in keys.items():
            if name == field_name:
                return f"{section}.{key}" if section else key
    return next((t for t, f in NESTED.items() if f == field_name),
                SHARED.get(field_name, field_name))


def named(field_name: str) -> str:
    """A field as an error message names it: the Python name, then the file's key."""
    key = file_key(field_name)
    return field_name if key == field_name else f"{field_name} ({key} in a scenario file)"


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
    planner: PlannerSpec            # the Head's planner: PsiGrid, CellWalk, PresetTwists, Park
    followers: FollowerRule         # TwoNeighbours (§2.3) or WaitForBehind (lab, §2.6.2.1)
    allow_reverse: bool             # False: followers stop instead of backing up
    wall_margin: float              # keep waypoints and start poses this far from walls (m)
    reach_radius: float = 0.06      # Head has reached its waypoint within this distance (m)
    avoid_radius: float = 0.2       # robots repel each other within this distance (m)
    avoid_gain: float = 0.15        # repulsion speed at contact (m/s)
    marker_jitter: float = 0.0      # tracker position noise per frame, beyond what the
    #                                 imaging chain makes (sigma, m): see `CameraChain`
    head_jitter_scale: float = 1.0  # the Head's marker jitter as a share of the others' (the
    #                                 real 3-robot Head's is lower: docs, decisions/sysid)
    walls: Walls | None = Walls()   # None: an open floor
    look: Look = Look()             # colours and lighting
    obstacles: tuple[Obstacle, ...] = ()    # static boxes and cylinders on the floor
    imaging: NoiseConfig = NoiseConfig()    # what the camera chain does to each frame
    markers: ColourMarkers | ArucoMarkers = ColourMarkers()     # what each robot wears
    tracking: TrackingLimits = TrackingLimits()     # when a tracked run fails its health
    frame_hz: float | None = None   # the camera's frame rate (None, "auto" in a file: the
    #                                 command rate, the text's 4 fps); frames land on the
    #                                 nearest physics step, so any rate is allowed
    frame_jitter: float = 0.0       # each frame's delay after its nominal instant, uniform in
    #                                 [0, frame_jitter) s: a tracker whose frames take uneven
    #                                 time, so each 2 Hz row's frame has an uneven age
    frame_alternation: float = 0.0  # the frames every other log row reads are taken this much
    #                                 earlier (s), the camera in step with the log: the rows
    #                                 alternate between two frame ages, a timing every robot
    #                                 of a row shares (the real ThymioLoc rows' speeds
    #                                 alternate: docs, reproduction/sim-to-real)

    wheel_spread: float = 0.0       # robots are not alike: each wheel's radius differs from
    #                                 the robot file's by a factor 1 + N(0, spread) drawn per
    #                                 episode (kept within +-3 spread), so each robot drives at
    #                                 its own speed and curves a little
    marker_offset: float = 0.0      # each robot's marker sits off its body's centre by
    #                                 N(0, offset) m per body axis, drawn per episode
    head_turn_speed: float = 0.0    # the share of its speed the Head keeps while turning
    #                                 toward a waypoint less than 90 deg off its heading: 0
    #                                 slows it by the cosine of its heading error (seed §2.3's
    #                                 unicycle tracking), 1 drives through at full speed (the
    #                                 real Head's speed hardly dips: docs, decisions/sysid)

    @property
    def camera_hz(self) -> float:
        """The rate frames are taken at (`frame_hz`, else the command rate)."""
        return self.command_hz if self.frame_hz is None else self.frame_hz

    def __post_init__(self) -> None:
        """Refuse, when the scenario is made, rates that are not whole physics steps and a
        camera that does not see the whole arena."""
        if not isinstance(self.name, str) or not self.name:
            raise UserError(f"the scenario's name must be a non-empty string, got {self.name!r}",
                            "name")
        self._check_numbers()
        check_camera(self.name, self.arena, self.camera)
        if 2 * self.wall_margin >= min(self.arena):
            raise UserError(f"{self.name}: {named('wall_margin')} {self.wall_margin:g} m leaves "
                            f"no floor inside the {self.arena[0]:g} x {self.arena[1]:g} m arena; "
                            "use a margin under half its width", "wall_margin")
        for i, ob in enumerate(self.obstacles):
            problem = ob.problem(self.arena)
            if problem is None and ob.height >= self.camera.height:
                problem = (f"stands {ob.height:g} m tall, up to the camera at "
                           f"{self.camera.height:g} m; lower it or raise the camera")
            if problem is not None:
                raise UserError(f"{self.name}: arena.obstacles[{i}] {problem}", "obstacles")
        try:                       # a planner the arena cannot hold, refused when read
            self.planner.build(self.arena, self.wall_margin, self.reach_radius, self.obstacles)
        except UserError as err:
            raise UserError(f"{self.name}: {err}", "planner") from None
        for what, hz in (("command", self.command_hz), ("log", self.log_hz)):
            if not hz > 0:
                raise UserError(f"{self.name}: the {what} rate {named(f'{what}_hz')} must be "
                                f"positive, got {hz:g} Hz", f"{what}_hz")
            steps_per_tick(1 / hz, self.physics.timestep, f"{self.name} {what}")
        self._check_frames()
        self._check_robot()

    def _check_frames(self) -> None:
        """A positive frame rate; a jitter that keeps every frame before the next one's
        nominal instant (frames stay in order); robots' spreads of a plausible size."""
        if self.frame_hz is not None and not (isinstance(self.frame_hz, int | float)
                                              and math.isfinite(self.frame_hz)
                                              and self.frame_hz > 0):
            raise UserError(f"{self.name}: {named('frame_hz')} must be a positive rate (Hz) "
                            f"or auto, got {self.frame_hz!r}", "frame_hz")
        for key in ("wheel_spread", "marker_offset"):
            v = getattr(self, key)
            if not (isinstance(v, int | float) and math.isfinite(v) and 0 <= v < 0.1):
                raise UserError(f"{self.name}: {named(key)} must be >= 0 and under 0.1 (a "
                                f"share for the wheels, metres for the marker), got {v!r}", key)
        j = self.frame_jitter
        if not (isinstance(j, int | float) and math.isfinite(j) and 0 <= j < 1 / self.camera_hz):
            raise UserError(f"{self.name}: {named('frame_jitter')} must be a delay >= 0 s "
                            f"under one frame period ({1 / self.camera_hz:g} s), got {j!r}",
                            "frame_jitter")
        a = self.frame_alternation
        if not (isinstance(a, int | float) and math.isfinite(a)
                and 0 <= a < min(1 / self.camera_hz, 1 / self.log_hz) - j):
            raise UserError(f"{self.name}: {named('frame_alternation')} must be a time >= 0 s "
                            "under one frame period less the frame_jitter "
                            f"({min(1 / self.camera_hz, 1 / self.log_hz) - j:g} s), got {a!r}",
                            "frame_alternation")

    def _check_robot(self) -> None:
        """The robot file meets the contract and can drive the Head's speed (the robot's
        XML is the one home of its top speed)."""
        if not isinstance(self.robot, str):
            raise UserError(f"{self.name}: {named('robot')} must be a robot's name or a "
                            f"robot.xml path, got {self.robot!r}", "robot")
        try:
            top = top_speed(self.robot)
        except UserError as err:
            raise UserError(f"{self.name}: {file_key('robot')}: {err}", "robot") from None
        if self.head_speed > top + 1e-9:
            raise UserError(f"{self.name}: {named('head_speed')} {self.head_speed:g} m/s is "
                            f"faster than the {self.robot}'s top speed {top:.3f} m/s; choose "
                            f"at most {top:.3f}", "head_speed")

    def _check_numbers(self) -> None:
        """NaN, infinite, zero or negative sizes, gains and speeds are refused here, so the
        Python API refuses what the CLI does (a chain with k_f = nan never moves)."""
        sizes = {"arena": self.arena, "spacing": self.spacing, "k_f": self.k_f, "k_t": self.k_t,
                 "k_omega": self.k_omega, "head_speed": self.head_speed,
                 "chain_speed": self.chain_speed, "reach_radius": self.reach_radius,
                 "avoid_radius": self.avoid_radius}
        for key, value in sizes.items():
            for v in (value if isinstance(value, tuple) else (value,)):
                if not (isinstance(v, int | float) and math.isfinite(v) and v > 0):
                    raise UserError(f"{self.name}: {named(key)} must be a positive finite "
                                    f"number, got {value!r}", key)
        dt = self.physics.timestep
        if not (isinstance(dt, int | float) and math.isfinite(dt) and dt > 0):
            raise UserError(f"{self.name}: physics.timestep must be a positive finite number "
                            f"of seconds, got {dt!r}", "physics")
        for key, v in {"wall_margin": self.wall_margin, "avoid_gain": self.avoid_gain,
                       "marker_jitter": self.marker_jitter,
                       "head_jitter_scale": self.head_jitter_scale}.items():
            if not (isinstance(v, int | float) and math.isfinite(v) and v >= 0):
                raise UserError(f"{self.name}: {named(key)} must be a non-negative finite "
                                f"number, got {v!r}", key)
        v = self.head_turn_speed
        if not (isinstance(v, int | float) and 0 <= v <= 1):
            raise UserError(f"{self.name}: {named('head_turn_speed')} must be a share in "
                            f"[0, 1], got {v!r}", "head_turn_speed")

    def as_made(self) -> ScenarioConfig:
        """The scenario as a run's outputs depend on it, for cache keys and run identities: the
        `[tracking]` limits judge outputs and make none (a loosened limit resumes a collection
        instead of simulating it again)."""
        return replace(self, tracking=TrackingLimits())

    def with_overrides(self, **kw: object) -> ScenarioConfig:
        """A copy with fields replaced, checked as a new scenario is."""
        unknown = sorted(set(kw) - {f.name for f in fields(self)})
        if unknown:
            raise UserError(f"ScenarioConfig has no field {', '.join(unknown)}; its fields are "
                            f"{', '.join(f.name for f in fields(self))}", unknown[0])
        return replace(self, **kw)


# The three built-in scenes' fovy are the hand-written XMLs' 2 atan(half-extent / height),
# rounded to 0.01 deg (kept so renders and tracked poses stay bit for bit; within 0.04 px of
# framing the arena exactly).
