"""Embedded scenarios (SPEC §3): typed, frozen configs; the one home of their constants.

A scenario describes its arena scene too (`arena`, `walls`, `camera`, `look`, `physics`: the
plain dataclasses of `chain.scene`, from which `scene.build_scene` generates the MJCF). Robot
geometry (wheel radius, track, top speed) is not repeated here: it is read from the robot's
compiled MJCF, so its XML stays the single source of truth.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from macrostate_mj.chain.motion import FollowerRule, TwoNeighbours, WaitForBehind
from macrostate_mj.chain.planners import CellWalk, PlannerSpec, PresetTwists, PsiGrid
from macrostate_mj.chain.scene import Camera, Look, Physics, Walls, check_camera
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

    def __post_init__(self) -> None:
        """Refuse, when the scenario is made, rates that are not whole physics steps and a
        camera that does not see the whole arena."""
        check_camera(self.name, self.arena, self.camera)
        for what, hz in (("command", self.command_hz), ("log", self.log_hz)):
            if not hz > 0:
                raise UserError(f"{self.name}: the {what} rate must be positive, got {hz:g} Hz")
            steps_per_tick(1 / hz, self.physics.timestep, f"{self.name} {what}")

    def with_overrides(self, **kw: object) -> ScenarioConfig:
        return replace(self, **kw)


# The three built-in scenes' fovy are the hand-written XMLs' 2 atan(half-extent / height),
# rounded to 0.01 deg (kept so renders and tracked poses stay bit for bit; within 0.04 px of
# framing the arena exactly).
SCENARIOS: dict[str, ScenarioConfig] = {
    # Physical testbed, seed §2.6.2: 2.5 x 1.9 m, Thymio II, Psi on a 12 x 8 grid.
    "lab": ScenarioConfig(
        name="lab", robot="thymio", arena=(2.5, 1.9), spacing=0.30,
        # 3 px/cm; fovy 2 atan(0.95 / 2.5). 5 ms: 50 steps a command, 100 a log tick.
        camera=Camera(height=2.5, resolution=(750, 570), fovy=41.61),
        physics=Physics(timestep=0.005, impratio=1.0),
        k_f=8.0, k_t=12.0, k_omega=1.2, head_speed=0.075, chain_speed=0.2, command_hz=4.0,
        log_hz=2.0, planner=PsiGrid((12, 8)), followers=WaitForBehind(0.05), allow_reverse=False,
        wall_margin=0.15, marker_jitter=0.00275,
    ),
    # Webots study, seed §3.4: 3 x 3 m, 10 x 10 grid, new waypoint on entering a new cell.
    "webots": ScenarioConfig(
        name="webots", robot="thymio", arena=(3.0, 3.0), spacing=0.30,
        # 2 px/cm; fovy 2 atan(1.5 / 3).
        camera=Camera(height=3.0, resolution=(600, 600), fovy=53.13),
        physics=Physics(timestep=0.005, impratio=1.0),
        k_f=3.0, k_t=3.0, k_omega=1.5, head_speed=0.12, chain_speed=0.2, command_hz=2.0,
        log_hz=2.0, planner=CellWalk((10, 10)), followers=TwoNeighbours(), allow_reverse=True,
        wall_margin=0.2,
    ),
    # Robotarium simulation, seed §2.5.2: 1.2 x 0.7, GRITSBot-like, preset Head velocities.
    "robotarium": ScenarioConfig(
        name="robotarium", robot="gritsbot", arena=(1.2, 0.7),
        # 5 px/cm; fovy 2 atan(0.35 / 1). 1/450 s: the 30 Hz ticks are 15 whole steps (2 ms
        # gave 16.67). Low walls, darker than the floor.
        camera=Camera(height=1.0, resolution=(600, 350), fovy=38.58),
        physics=Physics(timestep=1 / 450),
        walls=Walls(height=0.02, thickness=0.01),
        look=Look(floor_rgba=(0.85, 0.85, 0.85, 1.0), wall_rgba=(0.3, 0.3, 0.32, 1.0),
                  light_height=2.0),
        spacing=0.08, k_f=40.0, k_t=40.0, k_omega=4.0, head_speed=0.04, chain_speed=0.08,
        command_hz=30.0, log_hz=30.0, planner=PresetTwists(), followers=TwoNeighbours(),
        allow_reverse=True,
        wall_margin=0.08, reach_radius=0.02, avoid_radius=0.05, avoid_gain=0.04,
    ),
}

def get_scenario(name: str) -> ScenarioConfig:
    try:
        return SCENARIOS[name]
    except KeyError:
        raise UserError(
            f"unknown scenario {name!r}; choose one of {', '.join(SCENARIOS)}") from None


def scenario_for(name: str, head_speed: float | None = None) -> ScenarioConfig:
    """A named scenario, with the `--head-speed` override checked and applied."""
    cfg = get_scenario(name)
    if head_speed is not None:
        if not 0 < head_speed:
            raise UserError(f"--head-speed must be positive, got {head_speed}")
        cfg = cfg.with_overrides(head_speed=head_speed)
    return cfg
