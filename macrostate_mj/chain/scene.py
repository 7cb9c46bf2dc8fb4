"""The arena scene, generated with `mujoco.MjSpec` from what a scenario describes.

A scenario says its arena once (`arena`, the floor's size); the floor, the four walls on its
edges, the overhead camera that films it, the light and the physics options all follow from that
and from the small descriptions below, so nothing has to be kept in step by hand. Robots are
added by `chain.world`.

World frame: origin at the arena's centre, +x along its first side, +z up; the camera looks
straight down with image right = +x and image up = +y.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, replace

import mujoco
import numpy as np

from macrostate_mj.core.errors import UserError
from macrostate_mj.core.pixels import distort_normalized, lens_fold

# Smooth walls (priority 1: their low friction wins), so a robot pressed against a wall still
# turns on the spot instead of locking by friction. Robots touch walls through their contype-2
# footprint sphere only (robot.xml).
WALL_FRICTION = (0.05, 0.005, 0.0001)
WALL_PRIORITY = 1
WALL_CONTACT = 2                # contype = conaffinity
FLOOR_GRID = 0.05               # the plane's rendering grid spacing (m); no physical meaning
# A corner within half a pixel of the image's edge is imaged by the edge pixel.
EDGE_TOLERANCE_PX = 0.5
# Widest overhead lens: a camera low enough to need more frames the floor in theory but sees the
# markers edge-on near its corners (a camera 2 cm up "framed" the arena at 178 deg and tracked
# nothing).
MAX_FOVY = 120.0
# Points checked along each arena edge, corners included: a lens bends straight edges outward
# (pincushion) between corners that lie inside the image.
EDGE_SAMPLES = 33
SCALE_STEP = 1e-3               # m: the finite difference of `Camera.px_per_m_at`
DISTORTION_TERMS = ("k1", "k2", "p1", "p2")
# The k2 a folding lens is told to take: to this step, searched up to K2_REACH above its own.
K2_STEP = 1e-3
K2_REACH = 1e3


@dataclass(frozen=True)
class Camera:
    """The overhead camera, straight down over the arena's centre at `height` m."""

    height: float                       # above the floor (m)
    resolution: tuple[int, int]         # image (width, height) px; the offscreen buffer too
    fovy: float | None = None           # vertical field of view (deg); None frames the arena
    # The lens: OpenCV's radial-tangential [k1, k2, p1, p2] (normalized image coordinates, y
    # down). The renderer is an ideal pinhole; `vision.camera.Lens` bends its frames by these.
    distortion: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)

    def fovy_for(self, arena: tuple[float, float]) -> float:
        """`fovy`, or the narrowest one that sees the whole floor: 2 atan(half-extent / height)
        on the limiting axis (the x half-extent scaled by the image's aspect)."""
        if self.fovy is not None:
            return self.fovy
        w, h = self.resolution
        half = max(arena[1] / 2, arena[0] / 2 * h / w)
        return math.degrees(2 * math.atan(half / self.height))

    def focal_for(self, arena: tuple[float, float]) -> float:
        """The focal length (px) of the camera over `arena` (its fovy may follow the arena)."""
        return self.resolution[1] / 2 / math.tan(math.radians(self.fovy_for(arena)) / 2)

    def floor_pixels(self, arena: tuple[float, float], xy: np.ndarray) -> np.ndarray:
        """(k, 2) floor points (m, world) -> (k, 2) where the lens images them, in px from the
        image centre (u right, v down): the pinhole, then the lens's forward map."""
        xy = np.atleast_2d(np.asarray(xy, float))
        xd, yd = distort_normalized(xy[:, 0] / self.height, -xy[:, 1] / self.height,
                                    self.distortion)
        return np.column_stack([xd, yd]) * self.focal_for(arena)

    def px_per_m_at(self, arena: tuple[float, float], xy: np.ndarray) -> np.ndarray:
        """(k,) the image's local scale (px per m) at floor points (k, 2): the smaller singular
        value of d(pixel)/d(floor) by central differences, so a lens that squeezes one way
        reports that way's resolution."""
        xy = np.atleast_2d(np.asarray(xy, float))
        step = SCALE_STEP
        du = (self.floor_pixels(arena, xy + [step, 0]) - self.floor_pixels(arena, xy - [step, 0]))
        dv = (self.floor_pixels(arena, xy + [0, step]) - self.floor_pixels(arena, xy - [0, step]))
        jac = np.stack([du, dv], axis=-1) / (2 * step)                  # (k, 2, 2)
        return np.linalg.svd(jac, compute_uv=False)[:, -1]


@dataclass(frozen=True)
class Look:
    """Colours and lighting: what the renderer (and so the tracker) sees, not the physics."""

    floor_rgba: tuple[float, float, float, float] = (0.72, 0.72, 0.70, 1.0)
    wall_rgba: tuple[float, float, float, float] = (0.55, 0.55, 0.58, 1.0)
    light_height: float = 3.0           # the directional 'sun' (m); castshadow off
    light_diffuse: float = 0.45         # grey level of the sun
    headlight_ambient: float = 0.35     # grey levels of MuJoCo's headlight (no specular)
    headlight_diffuse: float = 0.45

    def __post_init__(self) -> None:
        for key in ("floor_rgba", "wall_rgba"):
            rgba = getattr(self, key)
            if len(rgba) != 4 or not all(isinstance(v, int | float) and 0 <= v <= 1
                                         for v in rgba):
                raise UserError(f"look.{key} must be four numbers in [0, 1] (red, green, blue, "
                                f"alpha), got {list(rgba)}", key)


@dataclass(frozen=True)
class Physics:
    """MuJoCo's `<option>`: the timestep is a scenario's, so its rates divide into whole steps."""

    timestep: float                     # s
    integrator: str = "implicitfast"    # a mjtIntegrator name without its prefix
    impratio: float | None = None       # None: MuJoCo's default
    cone: str = "elliptic"              # a mjtCone name without its prefix

    def __post_init__(self) -> None:
        """Unknown MuJoCo names are refused when the scenario is read, naming the key."""
        _enum(mujoco.mjtIntegrator, "mjINT_", self.integrator, "integrator")
        _enum(mujoco.mjtCone, "mjCONE_", self.cone, "cone")


@dataclass(frozen=True)
class Walls:
    """Four box walls on the floor's edges, outside it (the floor stays `arena`)."""

    height: float = 0.1                 # m
    thickness: float = 0.02             # m


# How many sizes each obstacle shape takes: its footprint's full extents, then optionally height.
OBSTACLE_SIZES = {"box": (2, 3), "cylinder": (1, 2)}
OBSTACLE_HEIGHT = Walls().height        # m, an obstacle's height when its size leaves it out


@dataclass(frozen=True)
class Obstacle:
    """A static box or cylinder standing on the floor, touched by robots like a wall.

    Sizes are full extents as a user measures them (not MuJoCo's half-sizes): a box's
    `[x, y]` or `[x, y, height]`, a cylinder's `[diameter]` or `[diameter, height]`; boxes are
    axis-aligned. `pos` is the footprint's centre (m, world frame)."""

    shape: str
    pos: tuple[float, float]
    size: tuple[float, ...]

    def problem(self, arena: tuple[float, float]) -> str | None:
        """What is wrong with it in an `arena`-sized floor, or None (the scenario words it)."""
        if self.shape not in OBSTACLE_SIZES:
            return f"shape must be one of {', '.join(OBSTACLE_SIZES)}, got {self.shape!r}"
        counts = OBSTACLE_SIZES[self.shape]
        if len(self.size) not in counts:
            what = "[x, y] or [x, y, height]" if self.shape == "box" else \
                "[diameter] or [diameter, height]"
            return f"a {self.shape}'s size is {what} (full extents, m), got {list(self.size)}"
        if not all(math.isfinite(v) and v > 0 for v in self.size):
            return f"sizes must be positive finite numbers, got {list(self.size)}"
        if not all(math.isfinite(v) for v in self.pos):
            return f"pos must be finite, got {list(self.pos)}"
        half = self.half_extents
        out = max(abs(self.pos[k]) + half[k] - arena[k] / 2 for k in range(2))
        if out > 1e-9:
            return (f"lies {out * 1000:.0f} mm outside the {arena[0]:g} x {arena[1]:g} m arena; "
                    "move it inside")
        return None

    @property
    def height(self) -> float:
        n = 2 if self.shape == "box" else 1
        return float(self.size[n]) if len(self.size) > n else OBSTACLE_HEIGHT

    @property
    def half_extents(self) -> tuple[float, float]:
        """Half the footprint's bounding box (m)."""
        if self.shape == "box":
            return self.size[0] / 2, self.size[1] / 2
        return self.size[0] / 2, self.size[0] / 2

    def within(self, xy: np.ndarray, radius: float) -> bool:
        """Is any point (k, 2) nearer than `radius` to the footprint (or inside it)? Cheaper
        than `distance`, from a bound of it: a box's largest per-axis gap never exceeds the
        distance to it."""
        return bool((-self.depth(xy) < radius).any())

    def depth(self, xy: np.ndarray) -> np.ndarray:
        """How deep (k,) points (k, 2) lie inside the footprint (m; 0 or less: outside, not
        the exact distance there). The health check's test, kept cheaper than `distance`: it
        runs at every check of every run."""
        d = np.abs(np.atleast_2d(xy) - self._centre)
        if self.shape == "cylinder":
            return self.size[0] / 2 - np.sqrt((d * d).sum(axis=1))
        return np.min(self._half - d, axis=1)

    @functools.cached_property
    def _centre(self) -> np.ndarray:
        """`pos` as an array, made once: the control tick measures against it per tick."""
        return np.asarray(self.pos, float)

    @functools.cached_property
    def _half(self) -> np.ndarray:
        return np.asarray(self.half_extents, float)

    def distance(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Signed distance (k,) from points (k, 2) to the footprint's outline (negative
        inside) and the unit outward direction (k, 2) there: what repulsion, health checks and
        the planner's clearance need."""
        d = np.atleast_2d(np.asarray(xy, float)) - self._centre
        if self.shape == "cylinder":
            r = np.linalg.norm(d, axis=1)
            safe = np.where(r > 1e-12, r, 1.0)[:, None]
            normal = np.where(r[:, None] > 1e-12, d / safe, [1.0, 0.0])
            return r - self.size[0] / 2, normal
        q = np.abs(d) - self._half
        outside = np.maximum(q, 0.0)
        dist_out = np.linalg.norm(outside, axis=1)
        inside = np.minimum(q.max(axis=1), 0.0)
        sign = np.where(d >= 0, 1.0, -1.0)
        normal = np.where(dist_out[:, None] > 0, outside * sign / np.maximum(dist_out, 1e-12)
                          [:, None], 0.0)
        face = np.argmax(q, axis=1)            # inside: the nearest face's normal
        rows = np.flatnonzero(dist_out == 0)
        normal[rows, face[rows]] = sign[rows, face[rows]]
        return dist_out + inside, normal


def blocked(obstacles: tuple[Obstacle, ...], xy: np.ndarray, clearance: float) -> np.ndarray:
    """(k,) which points (k, 2) lie within `clearance` of any obstacle (or inside one)."""
    xy = np.atleast_2d(np.asarray(xy, float))
    hit = np.zeros(len(xy), bool)
    for ob in obstacles:
        hit |= ob.distance(xy)[0] < clearance
    return hit


CORNERS = {"north-east": (1, 1), "north-west": (-1, 1), "south-west": (-1, -1),
           "south-east": (1, -1)}
# Each edge from one corner to the next (anticlockwise, as CORNERS).
EDGES = {"north": ("north-east", "north-west"), "west": ("north-west", "south-west"),
         "south": ("south-west", "south-east"), "east": ("south-east", "north-east")}


def arena_outline(arena: tuple[float, float]) -> tuple[np.ndarray, list[str]]:
    """(k, 2) floor points on the arena's outline, corners first, and what to call each:
    "north-east corner", "north edge", ..."""
    half = np.array(arena, float) / 2
    corner = {c: np.array(s, float) * half for c, s in CORNERS.items()}
    points = list(corner.values())
    names = [f"{c} corner" for c in CORNERS]
    t = np.linspace(0.0, 1.0, EDGE_SAMPLES)[1:-1, None]
    for edge, (a, b) in EDGES.items():
        points += list(corner[a] + t * (corner[b] - corner[a]))
        names += [f"{edge} edge"] * len(t)
    return np.array(points), names


def lens_words(distortion: tuple[float, float, float, float]) -> str:
    """The lens as a scenario file says it, e.g. "[k1, k2, p1, p2] = [-0.2, 0, 0, 0]"."""
    return f"[{', '.join(DISTORTION_TERMS)}] = [{', '.join(f'{c:g}' for c in distortion)}]"


def check_camera(name: str, arena: tuple[float, float], camera: Camera) -> None:
    """The camera can be rendered and sees the whole floor: its lens does not fold the image
    over itself (the renderer inverts it for every pixel) and every point of the arena's
    outline, through the lens, lands inside the image (the tracker cannot follow a robot it does
    not see). One line naming what fails."""
    w, h = camera.resolution
    if w < 1 or h < 1 or not camera.height > 0:
        raise UserError(f"{name}: the overhead camera needs a positive height and resolution, "
                        f"got height {camera.height:g} m and {w} x {h} px")
    if len(camera.distortion) != 4 or not all(math.isfinite(k) for k in camera.distortion):
        raise UserError(f"{name}: the overhead camera's distortion must be finite numbers, "
                        f"got {list(camera.distortion)}")
    fovy = camera.fovy_for(arena)
    if not 0 < fovy <= MAX_FOVY:
        raise UserError(f"{name}: the overhead camera's fovy is {fovy:.1f} deg (at most "
                        f"{MAX_FOVY:g}: a wider lens images markers too obliquely to track); "
                        f"raise camera.height ({camera.height:g} m) or narrow camera.fovy")
    focal = camera.focal_for(arena)
    points, names = arena_outline(arena)
    if any(camera.distortion):
        _check_fold(name, arena, camera, points)
    out = np.max(np.abs(camera.floor_pixels(arena, points)) - [w / 2, h / 2], axis=1)
    worst = int(np.argmax(out))
    if out[worst] > EDGE_TOLERANCE_PX:
        x, y = points[worst]
        pinhole = np.max(np.abs(points[worst] * focal / camera.height) - [w / 2, h / 2])
        wide = _fovy_that_frames(arena, camera, points)
        fix = ("raise its height or widen its fovy (leave fovy unset to frame the arena)"
               if pinhole > EDGE_TOLERANCE_PX else
               f"its lens {lens_words(camera.distortion)} bends it out of a frame fitted for an "
               "ideal lens: " + (f"set camera.fovy = {wide:.1f} (or more)" if wide is not None
                                 else "raise camera.height"))
        raise UserError(f"{name}: the overhead camera does not see the arena's {names[worst]} "
                        f"({x:g}, {y:g}) m, {out[worst]:.1f} px outside its {w} x {h} image; "
                        f"{fix}")


def _fovy_that_frames(arena: tuple[float, float], camera: Camera, points: np.ndarray
                      ) -> float | None:
    """The narrowest fovy (deg, to 0.1) whose frame, through the lens, holds every outline
    point, or None when even MAX_FOVY does not."""
    w, h = camera.resolution

    def fits(fovy: float) -> bool:
        uv = replace(camera, fovy=fovy).floor_pixels(arena, points)
        return bool(np.all(np.abs(uv) - [w / 2, h / 2] <= EDGE_TOLERANCE_PX))

    lo, hi = camera.fovy_for(arena), MAX_FOVY
    if not fits(hi):
        return None
    while hi - lo > 0.05:
        mid = (lo + hi) / 2
        lo, hi = (lo, mid) if fits(mid) else (mid, hi)
    return math.ceil(hi * 10) / 10


def _check_fold(name: str, arena: tuple[float, float], camera: Camera, points: np.ndarray
                ) -> None:
    """Refuse a lens whose forward map is not one-to-one over the image: the renderer's
    `vision.camera.Lens` finds each distorted pixel's pinhole source by inverting it, and past a
    fold there is none (the frame folds over itself and tracking fails by decimetres). A fold
    beyond the arena's image is refused too, not masked: a tracker's window reaches past the
    arena's edge, and no lens images two floor points on one pixel. The refusal names the k2
    that makes the lens one-to-one over the image, as the framing check names a fovy."""
    distortion = tuple(float(c) for c in camera.distortion)
    focal = camera.focal_for(arena)
    fold = _fold_px(camera.resolution, focal, distortion)
    if fold is None:
        return
    w, h = camera.resolution
    reach = float(np.hypot(*camera.floor_pixels(arena, points).T).max())
    where = (f"outside the arena's image ({reach:.0f} px out) but inside" if fold > reach
             else "inside the arena's image and")
    terms = " or ".join(f"|{t}|" for t, c in zip(DISTORTION_TERMS, distortion, strict=True)
                        if c and t != "k2")
    k2 = _unfolding_k2(camera.resolution, focal, distortion)
    fix = f"reduce {terms or '|k2|'}"
    if k2 is not None:
        unfolded = replace(camera, distortion=(distortion[0], k2, *distortion[2:]))
        moved = np.abs(unfolded.floor_pixels(arena, points)
                       - camera.floor_pixels(arena, points)).max()
        shift = f" and moves the arena's image by {moved:.1f} px at most" if fold > reach else ""
        fix = (f"set k2 = {k2:g} (or more), which makes it one-to-one over the image{shift}"
               f"{_and_fovy(arena, unfolded, points)}" + (f", or {fix}" if terms else ""))
    raise UserError(f"{name}: the overhead camera's lens {lens_words(distortion)} folds the "
                    f"image over itself {fold:.0f} px from its centre, {where} the {w} x "
                    f"{h} image (corners {math.hypot(w, h) / 2:.0f} px out); {fix}")


def _unfolding_k2(resolution: tuple[int, int], focal: float,
                  distortion: tuple[float, float, float, float]) -> float | None:
    """The smallest k2 above the lens's own (to K2_STEP, rounded up) that leaves the other
    terms as they are and folds nowhere in the image, or None when none up to K2_REACH does
    (a tangential fold). Raising k2 makes the radial gain's slope, 1 + 3 k1 r^2 + 5 k2 r^4,
    positive farther out; every k2 above 9 k1^2 / 20 keeps it positive everywhere."""
    w, h = resolution

    def unfolds(k2: float) -> bool:
        return lens_fold(w / 2 / focal, h / 2 / focal,
                         (distortion[0], k2, *distortion[2:])) is None

    lo, step = distortion[1], max(distortion[0] ** 2, K2_STEP)
    while not unfolds(lo + step):
        step *= 2
        if step > K2_REACH:
            return None
    hi = lo + step
    while hi - lo > K2_STEP / 4:
        mid = (lo + hi) / 2
        lo, hi = (lo, mid) if unfolds(mid) else (mid, hi)
    k2 = math.ceil(hi / K2_STEP) * K2_STEP
    return round(k2, 6) if unfolds(k2) else round(hi, 6)


def _and_fovy(arena: tuple[float, float], camera: Camera, points: np.ndarray) -> str:
    """", and camera.fovy = F" when the unfolded lens bends the arena out of the frame and a
    wider fovy both frames it and stays one-to-one; "" otherwise (the framing check then names
    its own fix)."""
    w, h = camera.resolution
    out = np.max(np.abs(camera.floor_pixels(arena, points)) - [w / 2, h / 2])
    if out <= EDGE_TOLERANCE_PX:
        return ""
    wide = _fovy_that_frames(arena, camera, points)
    if wide is None or _fold_px(camera.resolution, replace(camera, fovy=wide).focal_for(arena),
                                tuple(camera.distortion)) is not None:
        return ""
    return f", with camera.fovy = {wide:.1f} to frame the arena"


@functools.cache
def _fold_px(resolution: tuple[int, int], focal: float,
             distortion: tuple[float, float, float, float]) -> float | None:
    """`core.pixels.lens_fold` in px, once per camera (scenarios are made often)."""
    w, h = resolution
    fold = lens_fold(w / 2 / focal, h / 2 / focal, distortion)
    return None if fold is None else fold * focal


def build_scene(name: str, arena: tuple[float, float], walls: Walls | None, camera: Camera,
                look: Look, physics: Physics, obstacles: tuple[Obstacle, ...] = ()
                ) -> mujoco.MjSpec:
    """The arena as an `MjSpec`: floor `floor` (material `floor`), walls `wall_east/west/north/
    south` and obstacles `obstacle_<i>` (default class `wall`: robots touch them alike), light
    `sun`, camera `overhead` and an offscreen buffer of the camera's resolution."""
    check_camera(name, arena, camera)
    spec = mujoco.MjSpec()
    spec.modelname = name
    spec.compiler.degree = False
    spec.compiler.autolimits = True

    opt = spec.option
    opt.timestep = physics.timestep
    opt.integrator = _enum(mujoco.mjtIntegrator, "mjINT_", physics.integrator, "integrator")
    opt.cone = _enum(mujoco.mjtCone, "mjCONE_", physics.cone, "cone")
    if physics.impratio is not None:
        opt.impratio = physics.impratio

    vis = spec.visual
    vis.global_.offwidth, vis.global_.offheight = camera.resolution
    # No multisampling nor shadows: 3.5x cheaper on llvmpipe; the imaging chain's lens PSF
    # softens edges as a real camera's lens does (macrostate_mj/vision/imaging.py).
    vis.quality.shadowsize = 0
    vis.quality.offsamples = 0
    vis.headlight.ambient = [look.headlight_ambient] * 3
    vis.headlight.diffuse = [look.headlight_diffuse] * 3
    vis.headlight.specular = [0.0] * 3

    wall = spec.add_default("wall", spec.default).geom
    wall.type = mujoco.mjtGeom.mjGEOM_BOX
    wall.contype = wall.conaffinity = WALL_CONTACT
    wall.rgba = list(look.wall_rgba)
    wall.priority = WALL_PRIORITY
    wall.friction = list(WALL_FRICTION)

    spec.add_material(name="floor", rgba=list(look.floor_rgba), specular=0.0, shininess=0.0)

    world = spec.worldbody
    world.add_light(name="sun", pos=[0, 0, look.light_height], dir=[0, 0, -1],
                    type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL, castshadow=False,
                    diffuse=[look.light_diffuse] * 3)
    hx, hy = arena[0] / 2, arena[1] / 2
    world.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[hx, hy, FLOOR_GRID],
                   material="floor")
    if walls is not None:
        t, z = walls.thickness / 2, walls.height / 2                # half-sizes
        for side, pos, size in (("east", [hx + t, 0, z], [t, hy + t, z]),
                                ("west", [-hx - t, 0, z], [t, hy + t, z]),
                                ("north", [0, hy + t, z], [hx + 2 * t, t, z]),
                                ("south", [0, -hy - t, z], [hx + 2 * t, t, z])):
            world.add_geom(spec.find_default("wall"), name=f"wall_{side}", pos=pos, size=size)
    for i, ob in enumerate(obstacles):
        z = ob.height / 2
        if ob.shape == "box":
            kind, size = mujoco.mjtGeom.mjGEOM_BOX, [*ob.half_extents, z]
        else:
            kind, size = mujoco.mjtGeom.mjGEOM_CYLINDER, [ob.size[0] / 2, z, 0.0]
        world.add_geom(spec.find_default("wall"), name=f"obstacle_{i}", type=kind,
                       pos=[*ob.pos, z], size=size)
    world.add_camera(name="overhead", pos=[0, 0, camera.height], fovy=camera.fovy_for(arena),
                     resolution=list(camera.resolution))
    return spec


def _enum(kind: type, prefix: str, value: str, what: str) -> int:
    try:
        return getattr(kind, prefix + value.upper())
    except AttributeError:
        names = [n[len(prefix):].lower() for n in dir(kind) if n.startswith(prefix)]
        raise UserError(f"physics.{what}: unknown {what} {value!r}; choose one of "
                        f"{', '.join(names)}", what) from None
