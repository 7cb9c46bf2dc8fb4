"""A robot's meshes: the marker's top view, exact, and the mesh files of a CAD export read the way
MuJoCo will read them.

The top view is computed from MuJoCo's compiled triangles (the polygon moments of the faces that
look up) in numpy, not with trimesh: trimesh has no 2-D moments without shapely (not a
dependency), and importing it costs about half a second (scipy.spatial, networkx) at every robot
load. trimesh reads the STL and OBJ files a robot file references (watertight or not, a mesh at
all) and is imported only for a robot that has such files.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import mujoco
import numpy as np

if TYPE_CHECKING:
    import trimesh

MESH_SUFFIXES = (".stl", ".obj")   # what MuJoCo and trimesh both read (MuJoCo's .msh: MuJoCo only)


@dataclass(frozen=True)
class TopView:
    """A flat mesh seen from above (+z), on the xy plane: exact moments of its outline."""

    area: float                # m^2
    centroid: np.ndarray       # (2,) m
    covariance: np.ndarray     # (2, 2) second central moments over the area, m^2
    skew: float                # third central moment along x over the area, m^3: > 0 when the
    #                            outline's thin end (a triangle's apex) is at +x


def top_view(verts: np.ndarray, faces: np.ndarray) -> TopView:
    """The mesh with vertices `verts` (n, 3; +z up) and triangles `faces` (m, 3) seen from above.

    Sums over the faces that look up: a flat card's top faces tile its outline once (its bottom
    faces tile it again, its sides project to lines), so the sums are the outline's exact polygon
    moments. A surface wound the other way round (all faces looking down) is read from below.
    """
    tri = np.asarray(verts, np.float64)[np.asarray(faces, np.int64)][:, :, :2]   # (m, 3, 2)
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    signed = 0.5 * (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    if not (signed > 0).any():
        signed = -signed
    up = signed > 0
    tri, a = tri[up], signed[up]
    area = float(a.sum())
    if area <= 0:
        return TopView(0.0, np.full(2, np.nan), np.full((2, 2), np.nan), float("nan"))
    centroid = (a[:, None] * tri.sum(axis=1)).sum(axis=0) / (3 * area)
    q = tri - centroid
    s = q.sum(axis=1)                                                   # (m, 2)
    # Over a triangle with vertices v_k (sum s): the integral of x x^T is A/12 (sum v_k v_k^T
    # + s s^T), that of x^3 is A/60 (s^3 + 3 s sum v_k^2 + 2 sum v_k^3).
    second = np.einsum("m,mki,mkj->ij", a, q, q) + np.einsum("m,mi,mj->ij", a, s, s)
    x = q[:, :, 0]
    third = a @ (s[:, 0] ** 3 + 3 * s[:, 0] * (x**2).sum(1) + 2 * (x**3).sum(1))
    return TopView(area, centroid, second / (12 * area), float(third / (60 * area)))


def geom_faces(model: mujoco.MjModel, g: int) -> np.ndarray:
    """Mesh geom g's triangles (m, 3), indices into `geom_vertices`."""
    mesh = model.geom_dataid[g]
    adr, n = model.mesh_faceadr[mesh], model.mesh_facenum[mesh]
    return model.mesh_face[adr:adr + n]


def geom_vertices(model: mujoco.MjModel, g: int, data: mujoco.MjData | None = None,
                  body: int | None = None) -> np.ndarray:
    """Mesh geom g's compiled vertices (n, 3): without `data`, in the frame of the body that holds
    the geom; with it, at its pose there, in the world's frame or in `body`'s. MuJoCo re-centres
    and re-orients a compiled mesh; the geom's pose puts it back where the file put it."""
    mesh = model.geom_dataid[g]
    adr, n = model.mesh_vertadr[mesh], model.mesh_vertnum[mesh]
    verts = model.mesh_vert[adr:adr + n].astype(np.float64)
    if data is None:
        rot = np.zeros(9)
        mujoco.mju_quat2Mat(rot, model.geom_quat[g])
        return verts @ rot.reshape(3, 3).T + model.geom_pos[g]
    world = data.geom_xpos[g] + verts @ data.geom_xmat[g].reshape(3, 3).T
    if body is None:
        return world
    return (world - data.xpos[body]) @ data.xmat[body].reshape(3, 3)


def geom_file(model: mujoco.MjModel, g: int) -> str | None:
    """The file mesh geom g was read from (as MuJoCo resolved it), or None for a mesh written in
    the MJCF itself (vertices or a builtin shape)."""
    mesh = model.geom_dataid[g]
    if model.geom_type[g] != mujoco.mjtGeom.mjGEOM_MESH or mesh < 0 \
            or model.mesh_pathadr[mesh] < 0:
        return None
    start = model.mesh_pathadr[mesh]
    return bytes(model.paths[start:]).split(b"\0", 1)[0].decode()


def mesh_file(spec: mujoco.MjSpec, mesh: mujoco.MjsMesh) -> Path:
    """Where MuJoCo will look for the file of `mesh`: its `file` under the robot file's folder
    and `<compiler meshdir>` (either may be absolute)."""
    return Path(spec.modelfiledir or ".") / (spec.meshdir or "") / mesh.file


def read_mesh(path: Path) -> trimesh.Trimesh:
    """The triangle mesh in the STL or OBJ file at `path`, vertices welded (an STL repeats them
    per face), or ValueError saying what the file is instead."""
    if path.suffix.lower() == ".stl":
        _check_binary_stl(path)
    import trimesh  # here, not at import: half a second, for robots with mesh files only

    try:
        mesh = trimesh.load(path, force="mesh")
    except Exception as err:        # a parser's failure on a broken file: the file's fault
        raise ValueError(f"trimesh cannot read it ({type(err).__name__}: "
                         f"{' '.join(str(err).split())[:120]})") from None
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise ValueError("it holds no triangles")
    return mesh


def _check_binary_stl(path: Path) -> None:
    """MuJoCo reads binary STL only: an 80-byte header, a face count, 50 bytes a face."""
    raw = path.read_bytes()
    count = int.from_bytes(raw[80:84], "little") if len(raw) >= 84 else -1
    if count > 0 and len(raw) == 84 + 50 * count:
        return
    if raw.lstrip()[:5].lower() == b"solid":
        raise ValueError("it is an ASCII STL, which MuJoCo cannot read")
    raise ValueError("it is not a binary STL (its size does not match its face count)")


def open_edges(mesh: trimesh.Trimesh) -> int:
    """How many edges of `mesh` only one face uses: 0 when it is watertight."""
    import trimesh

    return len(trimesh.grouping.group_rows(mesh.edges_sorted, require_count=1))


def top_points(verts: np.ndarray, faces: np.ndarray, n: int = 101) -> np.ndarray:
    """(k, 2) the points of an n x n grid over the mesh's bounding box that its upward faces
    cover seen from above: the marker as a camera's pixels sample it (for the apex rule, which
    has no closed form)."""
    tri = np.asarray(verts, np.float64)[np.asarray(faces, np.int64)][:, :, :2]
    lo, hi = tri.reshape(-1, 2).min(axis=0), tri.reshape(-1, 2).max(axis=0)
    g = np.stack(np.meshgrid(*(np.linspace(lo[k], hi[k], n) for k in range(2))), -1)
    p = g.reshape(-1, 2)
    inside = np.zeros(len(p), bool)
    for a, b, c in tri:
        d = (b[1] - c[1]) * (a[0] - c[0]) + (c[0] - b[0]) * (a[1] - c[1])
        if abs(d) < 1e-18:
            continue
        l1 = ((b[1] - c[1]) * (p[:, 0] - c[0]) + (c[0] - b[0]) * (p[:, 1] - c[1])) / d
        l2 = ((c[1] - a[1]) * (p[:, 0] - c[0]) + (a[0] - c[0]) * (p[:, 1] - c[1])) / d
        inside |= (l1 >= 0) & (l2 >= 0) & (l1 + l2 <= 1)
    return p[inside]
