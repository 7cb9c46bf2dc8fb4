"""A robot's meshes (`chain.meshes`): the marker's top view is exact (and agrees with the 201 x 201
grid it replaced on every shipped robot), and a robot file whose shell is a CAD export of its own
(an STL or OBJ in its folder) passes, or is refused in one line naming the file, the geom and
the fix."""

import time

import cv2
import mujoco
import numpy as np
import pytest
import trimesh
from clitools import cli_inprocess

from macrostate_mj.chain.meshes import geom_faces, geom_vertices, top_view
from macrostate_mj.chain.robot import known_robots, load_robot
from macrostate_mj.chain.scenarios import SCENARIOS
from macrostate_mj.chain.world import build_world, marker_area
from macrostate_mj.core.errors import UserError
from macrostate_mj.core.paths import ASSETS

EPUCK = (ASSETS / "epuck" / "robot.xml").read_text()
SHELL = '<geom name="shell" class="shell" size="0.035 0.0235" pos="0 0 0.006"/>'
# The e-puck's body, 70 mm across and 47 mm tall, as a mesh file: its origin mid-height.
EPUCK_LAB = dict(robot="epuck", spacing=0.2, head_speed=0.06, chain_speed=0.129,
                 avoid_radius=0.13, avoid_gain=0.1, reach_radius=0.04, wall_margin=0.12)


def _grid_view(verts: np.ndarray, faces: np.ndarray) -> tuple[float, np.ndarray, np.ndarray, float]:
    """The marker check this module replaced: the top view sampled on a 201 x 201 grid over the
    mesh's bounding box (area, centroid, covariance, third moment along x)."""
    verts = verts[:, :2]
    tris = verts[faces]
    lo, hi = verts.min(0), verts.max(0)
    u, v = np.meshgrid(np.linspace(lo[0], hi[0], 201), np.linspace(lo[1], hi[1], 201))
    pts = np.column_stack([u.ravel(), v.ravel()])
    inside = np.zeros(len(pts), bool)
    for a, b, c in tris:
        det = (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1])
        if abs(det) < 1e-12:
            continue
        d = pts - a
        s = (d[:, 0] * (c[1] - a[1]) - d[:, 1] * (c[0] - a[0])) / det
        t = (d[:, 1] * (b[0] - a[0]) - d[:, 0] * (b[1] - a[1])) / det
        inside |= (s >= -1e-9) & (t >= -1e-9) & (s + t <= 1 + 1e-9)
    cell = (hi[0] - lo[0]) / 200 * (hi[1] - lo[1]) / 200
    pts = pts[inside]
    centre = pts.mean(axis=0)
    d = pts - centre
    return len(pts) * cell, centre, d.T @ d / len(d), float(np.mean(d[:, 0] ** 3))


@pytest.mark.parametrize("name", known_robots())
def test_the_exact_top_view_agrees_with_the_grid_on_every_shipped_robot(name):
    """Centroid within 0.1 mm, area within 1 %, the same principal axis and apex side; and
    faster (the times are printed: `pytest -s`)."""
    robot = load_robot(name)
    model, g = robot.model, robot.model.geom("marker").id
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    root = model.joint("root").bodyid[0]
    verts, faces = geom_vertices(model, g, data, root), geom_faces(model, g)
    t0 = time.perf_counter()
    grid = _grid_view(verts, faces)
    t1 = time.perf_counter()
    exact = top_view(verts, faces)
    t2 = time.perf_counter()
    print(f"\n{name}: grid area {grid[0] * 1e6:.2f} mm2, centroid {grid[1] * 1000} mm, "
          f"{(t1 - t0) * 1000:.2f} ms; exact {exact.area * 1e6:.2f} mm2, centroid "
          f"{exact.centroid * 1000} mm, {(t2 - t1) * 1000:.3f} ms")
    assert np.linalg.norm(exact.centroid - grid[1]) < 1e-4
    assert exact.area == pytest.approx(grid[0], rel=0.01)
    assert exact.covariance == pytest.approx(grid[2], rel=0.03, abs=1e-8)
    assert np.sign(exact.skew) == np.sign(grid[3]) == 1
    assert t2 - t1 < t1 - t0
    assert marker_area(model, "marker") == pytest.approx(exact.area, rel=1e-12)
    # The area the trackers expected before: OpenCV's convex hull of the authored vertices.
    authored = np.asarray(robot.spec.mesh("marker").uservert, np.float32).reshape(-1, 3)
    hull = cv2.contourArea(cv2.convexHull(np.ascontiguousarray(authored[:, :2])))
    assert exact.area == pytest.approx(hull, rel=1e-6)


def test_the_top_view_of_an_l_shaped_card_is_its_polygons():
    """A non-convex card: area, centroid and moments of the L (3 x 2 less a 2 x 1 corner), in
    either winding."""
    outline = np.array([[0, 0], [3, 0], [3, 1], [1, 1], [1, 2], [0, 2]], float)
    card = trimesh.creation.extrude_triangulation(
        outline, np.array([[0, 1, 2], [0, 2, 3], [0, 3, 4], [0, 4, 5]]), 0.002)
    for faces in (card.faces, card.faces[:, ::-1]):
        view = top_view(card.vertices, faces)
        assert view.area == pytest.approx(4.0)
        np.testing.assert_allclose(view.centroid, [1.25, 0.75])
        np.testing.assert_allclose(view.covariance, [[37 / 48, -0.1875], [-0.1875, 13 / 48]])
        assert view.skew == pytest.approx(0.28125)        # its long arm's end is at +x


def _robot(tmp_path, shell: trimesh.Trimesh | None = None, file: str = "meshes/shell.stl",
           mesh_attrs: str = "", geom_attrs: str = "", write: bool = True):
    """The e-puck with its body cylinder replaced by a mesh file in its folder."""
    folder = tmp_path / "bot"
    (folder / "meshes").mkdir(parents=True, exist_ok=True)
    if shell is None:
        shell = trimesh.creation.cylinder(radius=0.035, height=0.047, sections=48)
    if write:
        shell.export(folder / file)
    xml = EPUCK.replace(SHELL, '<geom name="shell" class="shell" type="mesh" mesh="shell" '
                               f'pos="0 0 0.006"{geom_attrs}/>')
    xml = xml.replace("<asset>", f'<asset>\n    <mesh name="shell" file="{file}"{mesh_attrs}/>')
    (folder / "robot.xml").write_text(xml)
    return folder / "robot.xml"


def test_a_robot_with_an_stl_shell_of_its_own_passes_and_runs(tmp_path):
    path = _robot(tmp_path)
    robot = load_robot(str(path), largest_team=10)
    assert robot.model.nmesh == 2
    plain = load_robot("epuck").model
    assert robot.model.body_mass[1] == pytest.approx(plain.body_mass[1])
    world = build_world(SCENARIOS["lab"].with_overrides(**{**EPUCK_LAB, "robot": str(path)}), 3)
    assert world.marker_area == pytest.approx(0.051 * 0.036 / 2, rel=1e-6)
    obj = _robot(tmp_path / "obj", file="meshes/shell.obj")
    load_robot(str(obj))


def _open_shell() -> trimesh.Trimesh:
    shell = trimesh.creation.cylinder(radius=0.035, height=0.047, sections=48)
    shell.update_faces(np.arange(len(shell.faces)) != 0)      # a hole: one triangle missing
    return shell


def _moved(dz: float = 0.0, scale: float = 1.0, radius: float = 0.035,
           height: float = 0.047) -> trimesh.Trimesh:
    shell = trimesh.creation.cylinder(radius=radius, height=height, sections=48)
    shell.apply_translation([0, 0, dz])
    shell.apply_scale(scale)
    return shell


# Each: the robot's shell file, and what the refusal must name (besides the file and the geom).
BROKEN = {
    "missing": (dict(write=False), ["no such file", "meshes/shell.stl", "export the part"]),
    "not a mesh": (dict(file="meshes/shell.obj", shell=trimesh.points.PointCloud(np.eye(3))),
                   ["not a mesh MuJoCo can read", "holds no triangles", "binary STL or OBJ"]),
    "text file": (dict(file="meshes/shell.stl", shell="hello"),
                  ["not a binary STL", "export the part as binary STL"]),
    "ascii stl": (dict(file="meshes/shell.stl", shell="ascii"),
                  ["ASCII STL", "export the part as binary STL"]),
    "not watertight": (dict(shell=_open_shell()),
                       ["not watertight (3 open edges)", "carries the geom's mass",
                        'inertia="shell"']),
    "below the floor": (dict(shell=_moved(dz=-0.01)),
                        ["7.0 mm below the floor", "raise it"]),
    "past the collider": (dict(shell=_moved(radius=0.04)),
                          ["40.0 mm from the body-collider's centre", "35.0 mm footprint"]),
    "millimetres": (dict(shell=_moved(scale=1000)),
                    ["past its 35.0 mm footprint", 'scale="0.001 0.001 0.001"']),
    "over the marker": (dict(shell=_moved(dz=0.01, height=0.05)),
                        ["rises 10.2 mm above the marker", "lower the part"]),
}


@pytest.mark.parametrize("case", sorted(BROKEN))
def test_a_broken_mesh_file_is_refused_in_one_line_naming_file_geom_and_fix(case, tmp_path):
    kw, words = BROKEN[case]
    kw = dict(kw)
    if isinstance(kw.get("shell"), str):
        text = kw.pop("shell")
        path = _robot(tmp_path, write=False, **kw)
        good = trimesh.creation.cylinder(radius=0.035, height=0.047)
        (path.parent / kw["file"]).write_bytes(
            b"hello\n" if text == "hello" else good.export(file_type="stl_ascii").encode())
    elif isinstance(kw.get("shell"), trimesh.points.PointCloud):
        points = kw.pop("shell")
        path = _robot(tmp_path, write=False, **kw)
        points.export(path.parent / kw["file"])
    else:
        path = _robot(tmp_path, **kw)
    with pytest.raises(UserError) as err:
        load_robot(str(path))
    text = str(err.value)
    assert "\n" not in text
    assert text.startswith(f"robot file {path}: geom 'shell'") or \
        text.startswith(f"robot file {path}: visible geom 'shell'"), text
    assert "shell.stl" in text or "shell.obj" in text, text
    for w in words:
        assert w in text, text


def test_an_open_shell_with_shell_inertia_or_no_mass_passes(tmp_path):
    """An open CAD shell is fine where no volume is asked of it: its inertia a surface's, or
    no mass at all; the robot loads with the shell as a mesh geom."""
    for where, attrs in (("a", {"mesh_attrs": ' inertia="shell"'}),
                         ("b", {"geom_attrs": ' mass="0"'})):
        model = load_robot(str(_robot(tmp_path / where, shell=_open_shell(), **attrs))).model
        shell = model.geom("shell")
        assert shell.type[0] == mujoco.mjtGeom.mjGEOM_MESH
        assert model.mesh_facenum[shell.dataid[0]] > 0


def test_the_cli_refuses_a_broken_mesh_with_exit_2_and_writes_nothing(tmp_path, capsys):
    path = _robot(tmp_path, write=False)
    scenario = tmp_path / "mine.toml"
    scenario.write_text(f'extends = "lab"\nname = "mine"\n\n[robot]\nmodel = "{path}"\n\n'
                        "[chain]\nspacing = 0.2\nhead_speed = 0.06\nchain_speed = 0.129\n"
                        "avoid_radius = 0.13\n")
    out = tmp_path / "scene.xml"
    code, _, err = cli_inprocess(capsys, "export-mjcf", "--scenario", str(scenario),
                                 "--robots", "3", "--out", str(out))
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "no such file" in lines[0] and "geom 'shell'" in lines[0], err
    assert not out.exists()
