"""The robot contract and the scene judged as rendered: no part of a robot, and no floor, wall or
obstacle, may look like a marker to the tracker under the scenario's lights.

`chain.robot.check_colours` judges a part by its authored rgba; the renderer lights it, and a
dark part comes out brighter than authored (rgba 0.08 0.1 0.18, value 46/255 as authored, renders
at saturation 96 and value 84 under the lab's lights: a marker colour in a team of 10, and tracked
poses 23 cm wrong). Here the robot is rendered as the overhead camera films it, a team of it
placed over the arena at several headings, under the scenario's look at its nominal and brightest
light (`NoiseConfig.light_scale`, sun straight down and tilted), and MuJoCo's segmentation says
which pixel is which geom; every non-marker pixel goes through the tracker's own classification
(`chain.markers.marker_of_pixels`). The scene is rendered the same way without robots (floor,
walls, obstacles), since a green floor passes every robot check and then pulls every green
marker's fit (129 mm off at the median in the lab). Rendering happens once per robot file, scene
and camera (`functools.cache`); judging a team size is then a few numpy passes.

The lens is left out: it moves pixels, not their colours.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import cv2
import mujoco
import numpy as np

from macrostate_mj.chain.markers import (
    MIN_SATURATION,
    MIN_VALUE,
    ColourMarkers,
    marker_colours,
    marker_of_pixels,
)
from macrostate_mj.chain.noise import NoiseConfig
from macrostate_mj.chain.robot import load_robot, robot_file
from macrostate_mj.chain.scene import Camera, Look, Obstacle, Physics, Walls, build_scene
from macrostate_mj.core.errors import UserError

if TYPE_CHECKING:
    from macrostate_mj.chain.scenario import ScenarioConfig

# A part is refused when, on one robot in one render, more of its pixels count for a marker
# than this share of that robot's marker pixels (and at least CLASH_MIN_PX): enough to pull the
# tracker's median and centroid of that marker's pixel set. A surface of the scene (floor, wall,
# obstacle) is refused by the same count against a robot's marker (the median over the shots),
# over the whole image: a robot may drive anywhere beside it.
CLASH_SHARE = 0.05
CLASH_MIN_PX = 4
# The team rendered: robots at these fractions of the arena's half-extents on both axes (its
# centre, and towards its edges and corners, where the camera sees their sides), each turned by
# HEADING_STEP from the last so every side faces the tilted light somewhere.
LAYOUT = (-0.75, 0.0, 0.75)
HEADING_STEP = math.radians(40.0)
GEOM = int(mujoco.mjtObj.mjOBJ_GEOM)
# What the robot's renders are cached by: its file and version, the arena, camera, look, light
# scales and tilt (`rendered_parts`' arguments).
RobotKey = tuple[str, int, tuple[float, float], Camera, Look, tuple[float, float], float]


@dataclass(frozen=True)
class RenderedParts:
    """The robot's non-marker pixels as filmed: per part (geom name in the robot file), its
    full-range HSV pixels, and for each pixel which (robot, render) shot it came from."""

    parts: tuple[str, ...]
    hsv: tuple[np.ndarray, ...]          # per part (k, 3) uint8
    shot: tuple[np.ndarray, ...]         # per part (k,) int: robot * renders + render
    marker_px: np.ndarray                # (shots,) the marker's pixel count in each shot


@dataclass(frozen=True)
class RenderedScene:
    """The scene's surfaces as filmed without robots: per geom (`floor`, `wall_<side>`,
    `obstacle_<i>`), its distinct full-range HSV colours, the render each was seen in, and how
    many pixels had it (a surface is a few colours over many pixels: judged once per colour)."""

    geoms: tuple[str, ...]
    hsv: tuple[np.ndarray, ...]          # per geom (k, 3) uint8
    shot: tuple[np.ndarray, ...]         # per geom (k,) int: which render
    count: tuple[np.ndarray, ...]        # per geom (k,) int: pixels of that colour there


def check_rendered_colours(cfg: ScenarioConfig, n: int) -> None:
    """Refuse, in one line, a surface of the scene (floor, wall, obstacle) or a robot part that
    the tracker would take for one of the markers of a team of `n`, as the scenario's camera
    films it under the scenario's lights. Scenarios whose markers are not colour markers have
    nothing to check. Cheap after the first call for a robot, scene and camera (the renders are
    cached)."""
    if not isinstance(cfg.markers, ColourMarkers):
        return
    path = robot_file(cfg.robot)
    # A scenario built from Python with lists is keyed as the file loader would make it.
    camera = replace(cfg.camera, resolution=tuple(cfg.camera.resolution),
                     distortion=tuple(cfg.camera.distortion))
    look = replace(cfg.look, floor_rgba=tuple(cfg.look.floor_rgba),
                   wall_rgba=tuple(cfg.look.wall_rgba))
    obstacles = tuple(Obstacle(ob.shape, tuple(ob.pos), tuple(ob.size)) for ob in cfg.obstacles)
    robot: RobotKey = (str(path), path.stat().st_mtime_ns, tuple(cfg.arena), camera, look,
             _light_scales(cfg.imaging), float(cfg.imaging.light_tilt_deg))
    problem = _scene_clash(robot, cfg.walls, obstacles, int(n))
    if problem is not None:
        raise UserError(f"{cfg.name}: {problem}", "look")
    problem = _clash(*robot, int(n))
    if problem is not None:
        raise UserError(f"robot file {path}: {problem}", "robot")


def _light_scales(noise: NoiseConfig) -> tuple[float, float]:
    """The sun's nominal scale and the brightest the imaging noise draws."""
    return 1.0, max(1.0, float(noise.light_scale[1]))


@functools.cache
def _clash(path: str, mtime: int, arena: tuple[float, float], camera: Camera, look: Look,
           scales: tuple[float, float], tilt_deg: float, n: int) -> str | None:
    """What part clashes with which marker of a team of n, worded, or None."""
    seen = rendered_parts(path, mtime, arena, camera, look, scales, tilt_deg)
    colours = marker_colours(n)
    need = np.maximum(CLASH_MIN_PX, CLASH_SHARE * seen.marker_px)
    for part, hsv, shot in zip(seen.parts, seen.hsv, seen.shot, strict=True):
        taken = marker_of_pixels(hsv, colours)
        for k in np.unique(taken[taken >= 0]):
            counts = np.bincount(shot[taken == k], minlength=len(need))
            worst = int(np.argmax(counts / need))
            if counts[worst] >= need[worst]:
                hsv_seen = np.median(hsv[(taken == k) & (shot == worst)], axis=0)
                return _words(f"geom {part!r}", hsv_seen,
                              f"{int(counts[worst])} px on one robot, whose marker shows "
                              f"{seen.marker_px[worst]:.0f} px", colours[k], int(k), n,
                              f"colour it darker or greyer (as rendered, value under {MIN_VALUE}"
                              f" or saturation under {MIN_SATURATION} of 255)")
    return None


@functools.cache
def _scene_clash(robot: RobotKey, walls: Walls | None, obstacles: tuple[Obstacle, ...], n: int
                 ) -> str | None:
    """What surface of the scene clashes with which marker of a team of n, worded, or None.
    `robot` is `_clash`'s key less n: the robot's renders give a marker's size as filmed."""
    _, _, arena, camera, look, scales, tilt_deg = robot
    marker_px = float(np.median(rendered_parts(*robot).marker_px))
    seen = rendered_scene(arena, walls, obstacles, camera, look, scales, tilt_deg)
    colours = marker_colours(n)
    need = max(CLASH_MIN_PX, CLASH_SHARE * marker_px)
    for geom, hsv, shot, count in zip(seen.geoms, seen.hsv, seen.shot, seen.count, strict=True):
        taken = marker_of_pixels(hsv, colours)
        for k in np.unique(taken[taken >= 0]):
            counts = np.bincount(shot[taken == k], weights=count[taken == k])
            worst = int(np.argmax(counts))
            if counts[worst] >= need:
                rows = (taken == k) & (shot == worst)
                hsv_seen = hsv[rows][int(np.argmax(count[rows]))]      # its commonest colour
                key = "floor_rgba" if geom == "floor" else "wall_rgba"   # obstacles: walls'
                rgba = getattr(look, key)
                # A grey of its brightness: grey lit by grey lights stays grey, as no marker is.
                grey = round(0.299 * rgba[0] + 0.587 * rgba[1] + 0.114 * rgba[2], 2)
                return _words(f"geom {geom!r} (look.{key} = {_listed(rgba)})", hsv_seen,
                              f"{int(counts[worst])} px in view, where a robot's marker shows "
                              f"{marker_px:.0f} px", colours[k], int(k), n,
                              f"colour it grey, e.g. look.{key} = "
                              f"{_listed((grey, grey, grey, rgba[3]))}")
    return None


def _listed(values: tuple[float, ...]) -> str:
    return f"[{', '.join(f'{v:g}' for v in values)}]"


def _words(what: str, hsv: np.ndarray, amount: str, colour: np.ndarray, k: int, n: int,
           fix: str) -> str:
    """The refusal: the part or surface, its colour as filmed, how much of it, the marker it
    passes for, the fix."""
    h, s, v = (int(c) for c in hsv)
    rgb = " ".join(str(int(c)) for c in cv2.cvtColor(
        np.uint8([[[h, s, v]]]), cv2.COLOR_HSV2RGB_FULL)[0, 0])
    marker = " ".join(str(round(float(c) * 255)) for c in colour)
    return (f"{what} renders at HSV {h} {s} {v} (RGB {rgb}, 0-255) under the scenario's "
            f"lights, which the tracker takes for marker {k + 1} of a team of {n} (RGB {marker}):"
            f" {amount}; {fix}")


@functools.cache
def rendered_parts(path: str, mtime: int, arena: tuple[float, float], camera: Camera,
                   look: Look, scales: tuple[float, float], tilt_deg: float) -> RenderedParts:
    """Render a team of the robot at `path` over a bare floor of the scenario's look, filmed
    by its overhead camera: segmentation once, colour at each light (`_lights`). `mtime` keys
    the cache on the file's version."""
    del mtime
    model, robots = _team_model(path, arena, camera, look)
    seg, frames = _render(model, camera, scales, tilt_deg)
    return _parts(model, robots, seg, frames)


@functools.cache
def rendered_scene(arena: tuple[float, float], walls: Walls | None,
                   obstacles: tuple[Obstacle, ...], camera: Camera, look: Look,
                   scales: tuple[float, float], tilt_deg: float) -> RenderedScene:
    """Render the scenario's scene without robots (floor, walls, obstacles) as its overhead
    camera films it, at each light (`_lights`), grouped by surface."""
    model = build_scene("scene", arena, walls, camera, look, Physics(timestep=0.005),
                        obstacles).compile()
    seg, frames = _render(model, camera, scales, tilt_deg)
    geom = np.where(seg[..., 1] == GEOM, seg[..., 0], -1)
    names, hsv, shot, count = [], [], [], []
    for g in range(model.ngeom):
        rows, cols = np.nonzero(geom == g)
        if not len(rows):
            continue
        # One code per (render, colour): the distinct colours and their pixel counts.
        codes = np.concatenate([(k << 24) | (f[rows, cols].astype(np.int64)
                                             @ np.array([1 << 16, 1 << 8, 1]))
                                for k, f in enumerate(frames)])
        codes, counts = np.unique(codes, return_counts=True)
        names.append(model.geom(g).name)
        hsv.append(np.column_stack([(codes >> s) & 255 for s in (16, 8, 0)]).astype(np.uint8))
        shot.append(codes >> 24)
        count.append(counts)
    return RenderedScene(tuple(names), tuple(hsv), tuple(shot), tuple(count))


def _render(model: mujoco.MjModel, camera: Camera, scales: tuple[float, float],
            tilt_deg: float) -> tuple[np.ndarray, list[np.ndarray]]:
    """The overhead camera's segmentation, then its full-range HSV frame at each light."""
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    w, h = camera.resolution
    renderer = mujoco.Renderer(model, height=h, width=w)
    try:
        renderer.enable_segmentation_rendering()
        renderer.update_scene(data, camera="overhead")
        seg = renderer.render().copy()
        renderer.disable_segmentation_rendering()
        frames = []
        for diffuse, direction in _lights(model, scales, tilt_deg):
            model.light_diffuse[:] = diffuse
            model.light_dir[:] = direction
            renderer.update_scene(data, camera="overhead")
            frames.append(cv2.cvtColor(renderer.render(), cv2.COLOR_RGB2HSV_FULL))
    finally:
        renderer.close()
    return seg, frames


def _team_model(path: str, arena: tuple[float, float], camera: Camera, look: Look
                ) -> tuple[mujoco.MjModel, list[str]]:
    """The scenario's floor, light and camera (no walls, no obstacles: they only hide robots)
    and a team of the robot laid out over it (`LAYOUT`), markers white."""
    spec = build_scene("rendered", arena, None, camera, look, Physics(timestep=0.005))
    spec.copy_during_attach = True
    robot = load_robot(path).spec
    names = []
    for i, (fx, fy) in enumerate((fx, fy) for fy in LAYOUT for fx in LAYOUT):
        name, yaw = f"r{i}", i * HEADING_STEP
        frame = spec.worldbody.add_frame(pos=[fx * arena[0] / 2, fy * arena[1] / 2, 0.0],
                                         quat=[math.cos(yaw / 2), 0, 0, math.sin(yaw / 2)])
        spec.attach(robot, prefix=f"{name}/", frame=frame)
        names.append(name)
    return spec.compile(), names


def _lights(model: mujoco.MjModel, scales: tuple[float, float], tilt_deg: float
            ) -> list[tuple[np.ndarray, np.ndarray]]:
    """(diffuse, direction) of each render, as `vision.imaging.SceneConditions` sets them: the
    nominal sun, the brightest straight down, the brightest tilted by the most the noise draws."""
    tilt = math.radians(tilt_deg)
    down = np.array([0.0, 0.0, -1.0])
    tilted = np.array([math.sin(tilt), 0.0, -math.cos(tilt)])
    nominal = model.light_diffuse.copy()
    return [(np.clip(nominal * scales[0], 0, 1), down),
            (np.clip(nominal * scales[1], 0, 1), down),
            (np.clip(nominal * scales[1], 0, 1), tilted)]


def _parts(model: mujoco.MjModel, robots: list[str], seg: np.ndarray,
           frames: list[np.ndarray]) -> RenderedParts:
    """Group the rendered pixels by robot part; count each shot's marker pixels."""
    geom = np.where(seg[..., 1] == GEOM, seg[..., 0], -1)
    renders = len(frames)
    part_of, robot_of = {}, {}
    for r, name in enumerate(robots):
        for g in range(model.ngeom):
            full = model.geom(g).name
            if full.startswith(f"{name}/"):
                part_of[g], robot_of[g] = full[len(name) + 1:] or str(g), r
    marker_px = np.zeros(len(robots) * renders)
    pixels: dict[str, list[tuple[np.ndarray, np.ndarray]]] = {}
    for g, part in part_of.items():
        rows, cols = np.nonzero(geom == g)
        if not len(rows):
            continue
        if part == "marker":
            marker_px[robot_of[g] * renders:(robot_of[g] + 1) * renders] = len(rows)
            continue
        for k, hsv in enumerate(frames):
            pixels.setdefault(part, []).append(
                (hsv[rows, cols], np.full(len(rows), robot_of[g] * renders + k)))
    parts = tuple(sorted(pixels))
    return RenderedParts(parts, tuple(np.concatenate([p[0] for p in pixels[q]]) for q in parts),
                         tuple(np.concatenate([p[1] for p in pixels[q]]) for q in parts),
                         np.maximum(marker_px, 1.0))
