"""World assembly: the scenario's arena scene plus N robot MJCFs, each with a marker of its own
(a colour or a tag: the scenario's `markers` object dresses them).

The scene is generated from the scenario (`chain.scene.build_scene`); the robot
(`macrostate_mj/assets/mjcf/<robot>/robot.xml`) is hand-written, and only the tedious part, N
prefixed copies with their colours, is generated here with `mujoco.MjSpec`. Robot geometry is
read back from the compiled model so the XML is the one source of truth for wheel radius, track
and top speed.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import mujoco
import numpy as np

from macrostate_mj.chain.meshes import geom_faces, geom_vertices, top_view
from macrostate_mj.chain.robot import load_robot
from macrostate_mj.chain.scenario import ScenarioConfig
from macrostate_mj.chain.scene import blocked, build_scene
from macrostate_mj.core.errors import UserError


def robot_names(n: int) -> list[str]:
    """Chain order [H, F1, ..., F{n-2}, T]; F1 is nearest the Head."""
    return ["H", *[f"F{i}" for i in range(1, n - 1)], "T"]


def chain_capacity(cfg: ScenarioConfig) -> int:
    """How many robots a snake layout at spacing d fits inside the walls' margin, clear of
    the obstacles by the same margin."""
    return len(_snake_slots(cfg))


def validate_chain(cfg: ScenarioConfig, robots: int, seconds: float) -> None:
    """A chain request's checks (the scenario checked itself when made): a team of `robots`
    that fits the arena, and a positive duration."""
    capacity = chain_capacity(cfg)
    if capacity < 2:
        raise UserError(f"{cfg.name}: the arena has room for no chain at spacing {cfg.spacing:g} "
                        f"m once its margin ({cfg.wall_margin:g} m) and obstacles are left "
                        "clear; shrink the obstacles, the margin (arena.margin) or the spacing",
                        "obstacles")
    if isinstance(robots, bool) or not isinstance(robots, int | np.integer):
        raise UserError(f"robots must be a whole number, got {robots!r}", "robots")
    if robots < 2:
        raise UserError(f"robots must be at least 2 (a Head and a Tail), got {robots}",
                        "robots")
    if robots > capacity:
        raise UserError(f"{robots} robots do not fit the {cfg.name} arena (at most "
                        f"{capacity} at spacing {cfg.spacing} m); use fewer robots", "robots")
    cfg.markers.check_team(robots)
    if not (isinstance(seconds, int | float) and seconds > 0 and seconds < float("inf")):
        raise UserError(f"seconds must be a positive finite number, got {seconds!r}", "seconds")


def place_chain(cfg: ScenarioConfig, n: int, rng: np.random.Generator) -> np.ndarray:
    """Start poses (n, 3): a straight chain at spacing d in a random place and direction, each
    robot facing the one ahead, with room for the Head to drive on (a Head facing a wall would
    have to U-turn through its own chain); a snake layout when no straight chain fits."""
    if n > chain_capacity(cfg):
        raise UserError(f"{n} robots do not fit the {cfg.name} arena at spacing {cfg.spacing} m "
                        f"(at most {chain_capacity(cfg)}); use fewer robots", "robots")
    half = np.array(cfg.arena) / 2 - cfg.wall_margin
    back = np.arange(-2, n)[:, None] * cfg.spacing
    for _ in range(500):
        phi = rng.uniform(-np.pi, np.pi)
        head = rng.uniform(-half, half)
        xy = head - back * np.array([np.cos(phi), np.sin(phi)])
        if np.all(np.abs(xy) <= half) and not _crosses_obstacle(cfg, xy):
            return np.column_stack([xy[2:], np.full(n, phi)])
    return _snake(cfg, n)


def _crosses_obstacle(cfg: ScenarioConfig, xy: np.ndarray) -> bool:
    """Does the straight chain through `xy` (its robots and the lines between them) pass
    within the wall margin of an obstacle? (Without obstacles: no, and no draws change.)"""
    if not cfg.obstacles:
        return False
    s = np.linspace(0.0, 1.0, 5)[:, None, None]
    line = (xy[:-1] + s * (xy[1:] - xy[:-1])).reshape(-1, 2)
    return bool(blocked(cfg.obstacles, line, cfg.wall_margin).any())


def _snake_slots(cfg: ScenarioConfig) -> np.ndarray:
    """The snake layout's free places (k, 2) in laying order: rows at spacing d from the
    arena's north-east margin corner, every other row reversed, those near an obstacle left
    out."""
    half = np.array(cfg.arena) / 2 - cfg.wall_margin
    span = np.array(cfg.arena) - 2 * cfg.wall_margin
    per_row, rows = (np.floor(span / cfg.spacing).astype(int) + 1)
    xy = []
    for k in range(per_row * rows):
        row, col = divmod(k, per_row)
        col = col if row % 2 == 0 else per_row - 1 - col
        xy.append([half[0] - col * cfg.spacing, half[1] - row * cfg.spacing])
    xy = np.array(xy)
    return xy[~blocked(cfg.obstacles, xy, cfg.wall_margin)] if cfg.obstacles else xy


def _snake(cfg: ScenarioConfig, n: int) -> np.ndarray:
    xy = _snake_slots(cfg)[:n]
    ahead = np.vstack([xy[0] + [cfg.spacing, 0], xy[:-1]])
    theta = np.arctan2(ahead[:, 1] - xy[:, 1], ahead[:, 0] - xy[:, 0])
    return np.column_stack([xy, theta])


@dataclass
class World:
    """A compiled chain world and the indices the simulation loop needs."""

    scenario: ScenarioConfig
    names: list[str]
    colours: np.ndarray
    spec: mujoco.MjSpec
    model: mujoco.MjModel
    body: np.ndarray            # each robot's root body (the freejoint's)
    qpos_adr: np.ndarray        # start of each robot's freejoint in qpos
    qvel_adr: np.ndarray
    ctrl_left: np.ndarray       # actuator index of each robot's left wheel
    ctrl_right: np.ndarray
    wheel_radius: float
    track: float
    max_wheel_speed: float
    marker_height: float        # world z of the marker's top face (the tracked plane)
    footprint_radius: float     # the robot-robot collider's radius: the robot's outline (m)

    @property
    def top_speed(self) -> float:
        return self.max_wheel_speed * self.wheel_radius

    @property
    def marker_area(self) -> float:
        """The area (m^2) of a robot's marker (card or tag plate) seen from above: what a
        tracker expects to see of it."""
        return marker_area(self.model, f"{self.names[0]}/marker")

    @functools.cached_property
    def marker_outline(self) -> np.ndarray:
        """(k, 2) the outline, in a robot's body frame (m), of the part of its marker a tracker
        must see to read it: the marker's convex hull seen from above, shrunk about its centroid
        to the markers' `pattern` (a tag's quiet border may be hidden). What occlusion tests."""
        from scipy.spatial import ConvexHull

        model = self.model
        g = model.geom(f"{self.names[0]}/marker").id
        verts = geom_vertices(model, g)
        hull = verts[ConvexHull(verts[:, :2]).vertices, :2]
        centre = top_view(verts, geom_faces(model, g)).centroid
        return centre + (hull - centre) * self.scenario.markers.pattern

    def to_xml(self) -> str:
        return self.spec.to_xml()


def check_start(cfg: ScenarioConfig, n: int, start: object) -> np.ndarray:
    """`start` as n poses (n, 3) of floats, or a UserError: not that shape, not finite, or a
    robot outside the walls (the arena's centre at the origin)."""
    try:
        poses = np.asarray(start, float)
    except (TypeError, ValueError):
        poses = np.empty(0)
    if poses.shape != (n, 3) or not np.isfinite(poses).all():
        raise UserError(f"start must be {n} finite poses (x, y, theta), an ({n}, 3) array; got "
                        f"{_described(start, poses)}", "start")
    if cfg.walls is not None and (np.abs(poses[:, :2]) > np.array(cfg.arena) / 2).any():
        raise UserError(f"start has a robot outside the {cfg.arena[0]:g} x {cfg.arena[1]:g} m "
                        "walls (their centre at the origin); place every robot inside them",
                        "start")
    return poses


def _described(start: object, poses: np.ndarray) -> str:
    if poses.size == 0 and not isinstance(start, np.ndarray):
        return f"{type(start).__name__} {start!r}"[:80]
    return f"shape {poses.shape}" + ("" if np.isfinite(poses).all() else " with NaN or inf")


def marker_area(world: mujoco.MjModel | mujoco.MjSpec, geom: str) -> float:
    """Area (m^2) of the flat marker geom `geom` seen from above in its body's frame, exact from
    its compiled mesh (`meshes.top_view`; a mesh file's too, and a card turned by its geom's
    pose). A spec is compiled first."""
    model = world if isinstance(world, mujoco.MjModel) else world.copy().compile()
    g = model.geom(geom).id
    return top_view(geom_vertices(model, g), geom_faces(model, g)).area


def build_world(cfg: ScenarioConfig, n: int, start: np.ndarray | None = None) -> World:
    """Compile the scene with n robots; `start` (n, 3) poses are baked in as the default
    qpos (the simulation resets poses itself, this matters for exported MJCF). `cfg` is
    resolved (`chain.scenarios.scenario_for` turns a built-in's name or a file into one)."""
    if not isinstance(cfg, ScenarioConfig):
        raise UserError(f"build_world takes a ScenarioConfig, not {cfg!r}: "
                        "chain.scenarios.scenario_for resolves a built-in's name or a file",
                        "scenario")
    validate_chain(cfg, n, 1.0)      # from Python too: a team that fits, a drivable Head speed
    start = check_start(cfg, n, place_chain(cfg, n, np.random.default_rng(0))
                        if start is None else start)
    names = robot_names(n)
    colours = cfg.markers.colours(n)
    spec = build_scene(cfg.name, cfg.arena, cfg.walls, cfg.camera, cfg.look, cfg.physics,
                       cfg.obstacles)
    spec.copy_during_attach = True
    robot = load_robot(cfg.robot, largest_team=cfg.markers.colour_teams(
        max(n, chain_capacity(cfg)))).spec
    for name, pose in zip(names, start, strict=True):
        frame = spec.worldbody.add_frame(pos=[pose[0], pose[1], 0.0],
                                         quat=[np.cos(pose[2] / 2), 0, 0, np.sin(pose[2] / 2)])
        spec.attach(robot, prefix=f"{name}/", frame=frame)
    cfg.markers.dress(spec, names, colours)
    model = spec.compile()
    body = np.array([model.joint(f"{nm}/root").bodyid[0] for nm in names])
    qpos_adr = np.array([model.joint(f"{nm}/root").qposadr[0] for nm in names])
    qvel_adr = np.array([model.joint(f"{nm}/root").dofadr[0] for nm in names])
    left = np.array([model.actuator(f"{nm}/wheel_left").id for nm in names])
    right = np.array([model.actuator(f"{nm}/wheel_right").id for nm in names])
    h = names[0]
    wheel_radius = float(model.geom(f"{h}/wheel_left").size[0])
    track = float(model.body(f"{h}/wheel_left").pos[1] - model.body(f"{h}/wheel_right").pos[1])
    max_wheel = float(model.actuator(f"{h}/wheel_left").ctrlrange[1])
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    # The marker mesh is re-centred by MuJoCo: its geom centre is mid-thickness (1 mm prism).
    marker_top = float(data.geom_xpos[model.geom(f"{h}/marker").id][2]) + 0.0005
    sphere = mujoco.mjtGeom.mjGEOM_SPHERE
    colliders = [g for g in range(model.ngeom) if model.geom_bodyid[g] == body[0]
                 and model.geom_contype[g] == 2 and model.geom_type[g] == sphere]
    footprint = float(model.geom_size[colliders[0], 0])
    return World(cfg, names, colours, spec, model, body, qpos_adr, qvel_adr, left, right,
                 wheel_radius, track, max_wheel, marker_top, footprint)
