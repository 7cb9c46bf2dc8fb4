"""The robot contract: what a `robot.xml` must hold for the chain code to drive, film and judge it.

A robot is hand-written MJCF (`macrostate_mj/assets/mjcf/<name>/robot.xml`; the contract in
words is `macrostate_mj/assets/mjcf/README.md`). The code finds its parts by name and trusts their
properties: the world builder reads wheel radius, track and top speed off the wheels and motors,
the tracker reads the `marker` mesh, the health monitor takes the free joint's authored height as
the rest height, and the physics choices (docs: explanation/physics) hang on contact bits. A file
that broke one of them would fail far from its cause (a KeyError deep in world assembly, or a
wheel climbing a neighbour in minute 7 of a soak), so every load goes through `load_robot`, which
checks the file once and names the first broken item and the file in one line.

Geometry is checked on the robot compiled alone, at its authored pose (body frame: origin at the
wheel-axle midpoint at axle height, +x forward, +y left, +z up; metres), mesh geoms by their exact
vertices. A mesh file (a user's CAD export, STL or OBJ) is read before MuJoCo reads it, so that a
missing, unreadable or open one is named with its geom and the fix (`chain.meshes`).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from macrostate_mj.chain.markers import (
    MIN_SATURATION,
    MIN_VALUE,
    apex_behind,
    marker_colours,
    taken_for_marker,
)
from macrostate_mj.chain.meshes import (
    MESH_SUFFIXES,
    geom_faces,
    geom_file,
    geom_vertices,
    mesh_file,
    open_edges,
    read_mesh,
    top_points,
    top_view,
)
from macrostate_mj.core.errors import UserError
from macrostate_mj.core.paths import ASSETS

ROBOT_FILE = "robot.xml"
CONTRACT = "macrostate_mj/assets/mjcf/README.md"
FLOOR_BIT = 1                  # contact bit of the floor: wheels, supports, shell
BODY_BIT = 2                   # contact bit of robot bodies and walls: the collider only
VISIBLE_GROUPS = range(3)      # geom groups MuJoCo renders by default (the overhead camera)
TOLERANCE = 5e-4               # m: how exactly parts must sit (axle, floor contact)
MARKER_THICKNESS = 0.002       # m: the marker is a flat card
MARKER_CENTRE = 0.001          # m: its centroid over the body origin (tracked pose = body pose)
MARKER_AXIS_DEG = 10.0         # its long axis this close to +x
MARKER_ELONGATION = 1.2        # second moments along / across at least this ratio
SUPPORT_FRICTION = 0.1         # a slider's or caster's sliding friction at most this
WHEELS = ("wheel_left", "wheel_right")


@dataclass(frozen=True)
class Robot:
    """A robot file that passed the contract: its spec (to attach), the model compiled alone."""

    name: str
    path: Path
    spec: mujoco.MjSpec
    model: mujoco.MjModel

    @property
    def top_speed(self) -> float:
        """Top wheel speed x wheel radius (m/s)."""
        m = self.model
        return float(m.actuator("wheel_left").ctrlrange[1] * m.geom("wheel_left").size[0])


def known_robots() -> list[str]:
    """The robots shipped as package data."""
    return sorted(p.parent.name for p in ASSETS.glob(f"*/{ROBOT_FILE}"))


def robot_file(robot: str) -> Path:
    """The file of `robot`: a shipped robot's name (`<ASSETS>/<name>/robot.xml`), or a path to a
    robot file or to a folder holding one (a robot of your own)."""
    if "/" not in robot and "\\" not in robot and not robot.endswith(".xml"):
        path = ASSETS / robot / ROBOT_FILE
        if not path.is_file():
            raise UserError(f"unknown robot {robot!r}; choose one of {', '.join(known_robots())} "
                            "or give the path of a robot.xml")
        return path
    path = Path(robot).expanduser()
    path = path / ROBOT_FILE if path.is_dir() else path
    if not path.is_file():
        raise UserError(f"robot file {path} does not exist; give a robot.xml or a shipped "
                        f"robot's name ({', '.join(known_robots())})")
    return path


def load_robot(robot: str, largest_team: int | None = None) -> Robot:
    """Parse, compile and check `robot` (a name or a path, see `robot_file`). With
    `largest_team`, also check that no visible part of it would be tracked as a marker in any
    team of 2 to `largest_team` robots (`check_colours`)."""
    path = robot_file(robot)
    try:
        spec = mujoco.MjSpec.from_file(str(path))
    except ValueError as err:
        raise UserError(f"robot file {path}: MuJoCo cannot load it: "
                        f"{' '.join(str(err).split())}") from None
    check_mesh_files(spec, path)
    try:
        model = spec.copy().compile()
    except ValueError as err:
        raise UserError(f"robot file {path}: MuJoCo cannot load it: "
                        f"{' '.join(str(err).split())}") from None
    check_robot(model, path)
    if largest_team is not None:
        check_colours(model, path, largest_team)
    return Robot(path.parent.name if path.name == ROBOT_FILE else path.stem, path, spec, model)


@functools.cache
def top_speed(robot: str) -> float:
    """Top wheel speed x wheel radius of `robot` (m/s), read off its checked MJCF (the one
    home of a robot's geometry and motor limits)."""
    return load_robot(robot).top_speed


class _Refusal:
    """Words the contract's one-line `UserError` for the file at `path`."""

    def __init__(self, path: Path | str):
        self.path = path

    def __call__(self, problem: str) -> UserError:
        return UserError(f"robot file {self.path}: {problem}; see the robot contract, {CONTRACT}")


def _compiled(robot: mujoco.MjSpec | mujoco.MjModel, path: Path | str) -> mujoco.MjModel:
    if isinstance(robot, mujoco.MjModel):
        return robot
    check_mesh_files(robot, path)
    try:
        return robot.copy().compile()
    except ValueError as err:
        raise _Refusal(path)(f"MuJoCo cannot compile it: {' '.join(str(err).split())}") from None


def _id(model: mujoco.MjModel, kind: mujoco.mjtObj, name: str) -> int:
    return mujoco.mj_name2id(model, kind, name)


def _extent(model: mujoco.MjModel, data: mujoco.MjData, g: int) -> tuple[np.ndarray, np.ndarray]:
    """World-frame (low, high) corners of geom g's bounding box at the authored pose."""
    centre = data.geom_xpos[g] + data.geom_xmat[g].reshape(3, 3) @ model.geom_aabb[g, :3]
    half = np.abs(data.geom_xmat[g].reshape(3, 3)) @ model.geom_aabb[g, 3:]
    return centre - half, centre + half


def _mesh_users(spec: mujoco.MjSpec, mesh: mujoco.MjsMesh) -> list[mujoco.MjsGeom]:
    return [g for g in spec.geoms
            if g.type == mujoco.mjtGeom.mjGEOM_MESH and g.meshname == mesh.name]


def check_mesh_files(spec: mujoco.MjSpec, path: Path | str) -> None:
    """Refuse (one line naming the robot file, the geom, the mesh file and the fix) a mesh file
    MuJoCo would fail on or load wrong: missing, not a binary STL or an OBJ, no triangles, or
    open (not watertight) while its geom carries mass, which MuJoCo spreads over the volume the
    surface encloses. Shape and place are checked on the compiled robot (`check_robot`)."""
    refuse = _Refusal(path)
    for mesh in spec.meshes:
        if not mesh.file or mesh.file in spec.assets:      # none, or given in memory
            continue
        users = _mesh_users(spec, mesh)
        what = (f"geom {users[0].name or '(unnamed)'!r}" if users else "a mesh of no geom") \
            + f" (mesh {mesh.name!r}, file {mesh.file})"
        file = mesh_file(spec, mesh)
        if not file.is_file():
            raise refuse(f"{what}: no such file {file}; export the part there, or fix the "
                         "<mesh file=...> (relative to the robot file's folder or <compiler "
                         "meshdir>)")
        suffix = file.suffix.lower()
        if suffix == ".msh":                    # MuJoCo's own binary mesh: MuJoCo checks it
            continue
        if suffix not in MESH_SUFFIXES:
            raise refuse(f"{what}: MuJoCo reads binary STL and OBJ mesh files, not "
                         f"{file.suffix or 'a file without a suffix'}; export the part as one")
        try:
            shell = read_mesh(file)
        except ValueError as err:
            raise refuse(f"{what} is not a mesh MuJoCo can read: {err}; export the part as "
                         "binary STL or OBJ") from None
        carries = [g for g in users if g.mass > 0 or (np.isnan(g.mass) and g.density > 0)]
        if carries and not shell.is_watertight \
                and mesh.inertia not in (mujoco.mjtMeshInertia.mjMESH_INERTIA_SHELL,
                                         mujoco.mjtMeshInertia.mjMESH_INERTIA_CONVEX):
            raise refuse(f"{what} is not watertight ({open_edges(shell)} open edges) but "
                         "carries the geom's mass, which MuJoCo spreads over the volume it "
                         "encloses; export a closed solid, give the <mesh> inertia=\"shell\", "
                         "or mass=\"0\" to the geom")


def check_robot(robot: mujoco.MjSpec | mujoco.MjModel, path: Path | str) -> None:
    """Refuse (`UserError`, one line naming the file and the first broken item) a robot that
    breaks the contract; `robot` is its spec or its model compiled alone."""
    model = _compiled(robot, path)
    refuse = _Refusal(path)
    obj = mujoco.mjtObj
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)

    # The pose: one free joint `root` on the one top-level body.
    root_joint = _id(model, obj.mjOBJ_JOINT, "root")
    if root_joint < 0 or model.jnt_type[root_joint] != mujoco.mjtJoint.mjJNT_FREE:
        raise refuse("no free joint named 'root' (the robot's pose in the world)")
    root = int(model.jnt_bodyid[root_joint])
    if model.body_parentid[root] != 0 or np.any(model.body_rootid[1:] != root):
        raise refuse("the free joint 'root' must sit on the one top-level body, with every other "
                     "body inside it")
    frame = data.xmat[root].reshape(3, 3)

    def local(p: np.ndarray) -> np.ndarray:                 # world point -> body frame
        return frame.T @ (p - data.xpos[root])

    # The wheels: hinge joints on their own bodies, velocity motors, floor-only cylinders.
    radius, top = {}, {}
    for wheel in WHEELS:
        body = _id(model, obj.mjOBJ_BODY, wheel)
        joint = _id(model, obj.mjOBJ_JOINT, wheel)
        geom = _id(model, obj.mjOBJ_GEOM, wheel)
        motor = _id(model, obj.mjOBJ_ACTUATOR, wheel)
        if body < 0 or model.body_parentid[body] != root:
            raise refuse(f"no body {wheel!r} inside the root body (the wheel; its position "
                         "gives the track)")
        if joint < 0 or model.jnt_type[joint] != mujoco.mjtJoint.mjJNT_HINGE \
                or model.jnt_bodyid[joint] != body:
            raise refuse(f"no hinge joint {wheel!r} on body {wheel!r} (the wheel's axle)")
        if float(frame[:, 1] @ data.xaxis[joint]) < 1 - 1e-6:
            raise refuse(f"joint {wheel!r} must turn about the body's +y axis (positive speed "
                         "drives forward)")
        if geom < 0 or model.geom_bodyid[geom] != body \
                or model.geom_type[geom] != mujoco.mjtGeom.mjGEOM_CYLINDER:
            raise refuse(f"no cylinder geom {wheel!r} on body {wheel!r} (its radius is the wheel "
                         "radius)")
        if model.geom_contype[geom] != 0 or model.geom_conaffinity[geom] != FLOOR_BIT:
            raise refuse(f"geom {wheel!r} must touch the floor only (contype 0, conaffinity "
                         f"{FLOOR_BIT}): a wheel touching a neighbour climbs it")
        if motor < 0 or model.actuator_trntype[motor] != mujoco.mjtTrn.mjTRN_JOINT \
                or model.actuator_trnid[motor, 0] != joint:
            raise refuse(f"no actuator {wheel!r} on joint {wheel!r} (the wheel's motor)")
        kv, bias = model.actuator_gainprm[motor, 0], model.actuator_biasprm[motor, :3]
        if not (model.actuator_gaintype[motor] == mujoco.mjtGain.mjGAIN_FIXED and kv > 0
                and model.actuator_biastype[motor] == mujoco.mjtBias.mjBIAS_AFFINE
                and bias[0] == 0 and bias[1] == 0 and bias[2] == -kv):
            raise refuse(f"actuator {wheel!r} must be a <velocity> servo (its ctrl is the "
                         "wheel's speed in rad/s)")
        lo, hi = model.actuator_ctrlrange[motor]
        if not (model.actuator_ctrllimited[motor] and hi > 0 and lo == -hi):
            raise refuse(f"actuator {wheel!r} needs a symmetric ctrlrange '-w w' (w: the top "
                         "wheel speed, rad/s)")
        if not model.actuator_forcelimited[motor]:
            raise refuse(f"actuator {wheel!r} needs a forcerange (the motor's torque limit, N m): "
                         "an unlimited motor tips the robot when it brakes")
        at = local(data.xpos[body])
        if abs(at[0]) > TOLERANCE or abs(at[2]) > TOLERANCE:
            raise refuse(f"body {wheel!r} must sit on the axle, at x = z = 0 of the body frame "
                         f"(it is at x = {at[0]:.4f}, z = {at[2]:.4f} m)")
        radius[wheel], top[wheel] = float(model.geom_size[geom, 0]), float(hi)
    y_left = float(local(data.xpos[model.body("wheel_left").id])[1])
    y_right = float(local(data.xpos[model.body("wheel_right").id])[1])
    if not (y_left > 0 > y_right and abs(y_left + y_right) <= TOLERANCE):
        raise refuse("the wheels must sit symmetric about the body's x axis, 'wheel_left' at +y "
                     f"(they are at y = {y_left:.4f} and {y_right:.4f} m)")
    if radius["wheel_left"] != radius["wheel_right"] or top["wheel_left"] != top["wheel_right"]:
        raise refuse("the two wheels must have the same radius and the same ctrlrange")
    axle_height = float(data.xpos[root][2])
    if abs(axle_height - radius["wheel_left"]) > TOLERANCE:
        raise refuse(f"the root body must stand at axle height, the wheel radius "
                     f"{radius['wheel_left']:.4f} m, so the wheels rest on the floor (it is at "
                     f"z = {axle_height:.4f} m; the health monitor takes it for the rest height)")

    floor = axle_height - radius["wheel_left"]
    _check_mesh_geoms(model, data, root, floor, local, refuse)
    _check_marker(model, data, root, refuse)

    # Contacts: one frictionless body-collider sphere; everything else touches the floor only.
    names = [model.geom(g).name or f"#{g}" for g in range(model.ngeom)]
    colliders = [g for g in range(model.ngeom)
                 if (model.geom_contype[g] | model.geom_conaffinity[g]) & BODY_BIT]
    if not colliders:
        raise refuse(f"no body-collider sphere (contype = conaffinity = {BODY_BIT}, condim 1) "
                     "on the root body: the robot would pass through robots and walls")
    for g in colliders:
        if not (model.geom_bodyid[g] == root and model.geom_type[g] == mujoco.mjtGeom.mjGEOM_SPHERE
                and model.geom_contype[g] == BODY_BIT and model.geom_conaffinity[g] == BODY_BIT
                and model.geom_condim[g] == 1):
            raise refuse(f"geom {names[g]!r} touches robots or walls (contact bit {BODY_BIT}); "
                         "only one frictionless sphere on the root body may (contype = "
                         f"conaffinity = {BODY_BIT}, condim 1: side contacts stay horizontal)")
    if len(colliders) > 1:
        raise refuse(f"{len(colliders)} body-collider spheres "
                     f"({', '.join(names[g] for g in colliders)}); keep exactly one")
    supports = 0
    for g in range(model.ngeom):
        if g in colliders:
            continue
        if model.geom_contype[g] != 0 or model.geom_conaffinity[g] not in (0, FLOOR_BIT):
            raise refuse(f"geom {names[g]!r} must touch the floor only or nothing (contype 0, "
                         f"conaffinity 0 or {FLOOR_BIT}); robots touch through the collider alone")
        if model.geom_conaffinity[g] != FLOOR_BIT:
            continue
        bottom = float(_low_high(model, data, g)[0][2]) - floor
        if bottom < -TOLERANCE:
            raise refuse(f"geom {names[g]!r} reaches {-bottom * 1000:.1f} mm below the floor at "
                         "rest; it would push the robot up")
        if names[g] in WHEELS or bottom > TOLERANCE:
            continue
        supports += 1
        if model.geom_priority[g] < 1 or model.geom_friction[g, 0] > SUPPORT_FRICTION:
            raise refuse(f"geom {names[g]!r} rests on the floor beside the wheels, so it must "
                         f"slide: priority='1' and sliding friction at most {SUPPORT_FRICTION} "
                         "(without priority the floor's friction wins and it drags)")
    if supports == 0:
        raise refuse("nothing but the wheels rests on the floor; add a slider or casters "
                     "(floor-only, priority='1', low friction) to keep the robot level")


def _low_high(model: mujoco.MjModel, data: mujoco.MjData, g: int) -> tuple[np.ndarray, np.ndarray]:
    """World-frame (low, high) corners of geom g at the authored pose: a mesh's exact, from its
    vertices; other geoms' from their bounding boxes."""
    if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH:
        verts = geom_vertices(model, g, data)
        return verts.min(axis=0), verts.max(axis=0)
    return _extent(model, data, g)


def _named(model: mujoco.MjModel, g: int) -> str:
    """'geom NAME', and its mesh file where it has one (what a user's CAD export is called)."""
    file = geom_file(model, g)
    return f"geom {model.geom(g).name or g!r}" + (f" (mesh file {file})" if file else "")


def _check_mesh_geoms(model: mujoco.MjModel, data: mujoco.MjData, root: int, floor: float,
                      local: Callable[[np.ndarray], np.ndarray], refuse: _Refusal) -> None:
    """A mesh file's part (a CAD export), seen or touching the floor, stays inside the
    body-collider's footprint and above the floor, by its exact vertices."""
    colliders = [g for g in range(model.ngeom) if model.geom_bodyid[g] == root
                 and model.geom_type[g] == mujoco.mjtGeom.mjGEOM_SPHERE
                 and model.geom_contype[g] & BODY_BIT]
    for g in range(model.ngeom):
        if geom_file(model, g) is None or not (model.geom_group[g] in VISIBLE_GROUPS
                                               or model.geom_conaffinity[g] & FLOOR_BIT):
            continue
        verts = geom_vertices(model, g, data, root)
        size = float(np.ptp(verts, axis=0).max())
        units = (" (exported in millimetres? give its <mesh> scale=\"0.001 0.001 0.001\")"
                 if size > 0.5 else "")
        if len(colliders) == 1:
            c = colliders[0]
            centre = local(data.geom_xpos[c])
            reach = float(np.hypot(*(verts[:, :2] - centre[:2]).T).max())
            footprint = float(model.geom_size[c, 0])
            if reach > footprint + TOLERANCE:
                raise refuse(f"{_named(model, g)} reaches {reach * 1000:.1f} mm from the "
                             f"body-collider's centre, past its {footprint * 1000:.1f} mm "
                             f"footprint{units}: robots would overlap on video before they "
                             "touch; trim or scale the part, or make the collider the robot's "
                             "outline")
        bottom = float(geom_vertices(model, g, data)[:, 2].min()) - floor
        if bottom < -TOLERANCE:
            raise refuse(f"{_named(model, g)} reaches {-bottom * 1000:.1f} mm below the floor "
                         f"at rest{units}; raise it (the geom's pos) or export it with its "
                         "origin where robot.xml places it")


def _check_marker(model: mujoco.MjModel, data: mujoco.MjData, root: int,
                  refuse: _Refusal) -> None:
    """The marker: a flat mesh on top, centred over the body origin, apex forward."""
    g = _id(model, mujoco.mjtObj.mjOBJ_GEOM, "marker")
    mesh = _id(model, mujoco.mjtObj.mjOBJ_MESH, "marker")
    if g < 0 or model.geom_bodyid[g] != root or model.geom_type[g] != mujoco.mjtGeom.mjGEOM_MESH \
            or mesh < 0 or model.geom_dataid[g] != mesh:
        raise refuse("no geom 'marker' of mesh 'marker' on the root body (the coloured card "
                     "the tracker finds; the world builder colours it)")
    if model.geom_contype[g] != 0 or model.geom_conaffinity[g] != 0 \
            or model.geom_group[g] not in VISIBLE_GROUPS:
        raise refuse("geom 'marker' must touch nothing (contype = conaffinity = 0) and be in a "
                     "rendered group (0-2)")
    low, high = _low_high(model, data, g)
    if high[2] - low[2] > MARKER_THICKNESS + 1e-9:
        raise refuse(f"geom 'marker' must be flat, at most {MARKER_THICKNESS * 1000:g} mm thick "
                     f"(it is {(high[2] - low[2]) * 1000:.1f} mm)")
    for other in range(model.ngeom):
        if other == g or model.geom_group[other] not in VISIBLE_GROUPS \
                or model.geom_rgba[other, 3] <= 0:
            continue
        rise = float(_low_high(model, data, other)[1][2] - high[2])
        if rise > 0:
            if geom_file(model, other) is None:
                raise refuse(f"visible geom {model.geom(other).name or other!r} rises above "
                             "the marker; the overhead camera must see the whole marker")
            raise refuse(f"visible {_named(model, other)} rises {rise * 1000:.1f} mm above "
                         "the marker, which the overhead camera must see whole; lower the part "
                         "or raise the marker (its geom's pos) above it")
    # The top view: the mesh projected into the body frame's xy plane, exact (`meshes.top_view`).
    view = top_view(geom_vertices(model, g, data, root), geom_faces(model, g))
    if not view.area > 0:
        raise refuse("geom 'marker' covers no area seen from above; lay the card flat")
    off = float(np.hypot(*view.centroid))
    if off > MARKER_CENTRE:
        raise refuse(f"the marker's centroid must sit over the body origin (it is "
                     f"{off * 1000:.1f} mm off): the tracker reports the centroid "
                     "as the robot's position")
    vals, vecs = np.linalg.eigh(view.covariance)
    axis = vecs[:, 1]                                   # the principal (long) axis
    angle = np.degrees(np.arccos(min(1.0, abs(float(axis[0])))))
    pts = top_points(geom_vertices(model, g, data, root), geom_faces(model, g)) - view.centroid
    if vals[1] < MARKER_ELONGATION * vals[0] or angle > MARKER_AXIS_DEG or view.skew <= 0 \
            or apex_behind(pts[:, 0], pts[:, 1]):
        raise refuse("the marker must be longer along +x than across, with its apex (the thin "
                     "end, the narrower half) forward at +x: the tracker reads the heading from "
                     "its shape")


def check_colours(robot: mujoco.MjSpec | mujoco.MjModel, path: Path | str,
                  largest_team: int) -> None:
    """Refuse a robot whose visible parts (other than its marker) the tracker would take for a
    marker in a team of 2 to `largest_team` robots, by the tracker's own rule
    (`chain.markers.taken_for_marker`): e.g. a green shell in a team of 3."""
    model = _compiled(robot, path)
    marker = _id(model, mujoco.mjtObj.mjOBJ_GEOM, "marker")
    seen = []                                   # (geom, rgb) of every visible non-marker colour
    for g in range(model.ngeom):
        if g == marker or model.geom_group[g] not in VISIBLE_GROUPS:
            continue
        rgbas = [model.geom_rgba[g]]
        if model.geom_matid[g] >= 0:
            rgbas.append(model.mat_rgba[model.geom_matid[g]])
        seen += [(g, rgba[:3]) for rgba in rgbas if rgba[3] > 0]
    for n in range(2, max(2, largest_team) + 1):
        colours = marker_colours(n)
        for g, rgb in seen:
            k = taken_for_marker(rgb, colours)
            if k is not None:
                colour = " ".join(f"{c:g}" for c in np.round(rgb, 3))
                raise _Refusal(path)(
                    f"visible geom {model.geom(g).name or g!r} (rgba {colour}) would be tracked "
                    f"as marker {k + 1} of a team of {n}; colour the robot's parts other than "
                    f"its marker grey (saturation under {MIN_SATURATION}/255) or dark (value "
                    f"under {MIN_VALUE}/255)")
