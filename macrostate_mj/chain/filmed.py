"""What a tracked run checks up front about what its camera films, and `scenario check` with it:
one rule for both, so a scenario that `scenario check` passes is not refused or failed by a run
for something that was known before it started.

Colours (colour markers): no robot part and no floor, wall or obstacle may pass for a marker as
rendered (`chain.rendered`). Tags (ArUco markers): each tag's cells must be wide enough in pixels,
through the lens, at every corner of the arena, for the detector to read them after the imaging
chain's blur and noise (`MIN_TAG_CELL_PX`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from macrostate_mj.chain.rendered import check_rendered_colours
from macrostate_mj.chain.scene import CORNERS, check_camera
from macrostate_mj.chain.tags import ArucoMarkers
from macrostate_mj.chain.world import build_world
from macrostate_mj.core.errors import UserError

if TYPE_CHECKING:
    from macrostate_mj.chain.scenario import ScenarioConfig

# The narrowest tag cell (px, at the marker plane, through the lens) the run's tag detector
# (`vision.aruco.ArucoTracker`) reads in every frame under the default imaging noise (blur
# 1.5 px, PSF 0.4 px, sensor noise 3, JPEG 75-95). Measured with examples/tag_hall.toml (e-puck,
# DICT_4X4_50) at a fixed fovy of 53.13 deg and the camera raised from 4 to 7 m, `simulate
# --track --robots 20 --seconds 30` over seeds 1-4 (10 robots, seed 0, at some heights): the
# worst robot's detected share of the rows was 100 % at 3.49 and 3.24 px a cell, 91.7-98.3 %
# at 3.13 and 3.01, 88.3-96.7 % at 2.78, 88.3 % at 2.53, 86.7 % at 2.31, 60 % at 1.98.
MIN_TAG_CELL_PX = 3.2


@dataclass(frozen=True)
class TagCells:
    """How wide a tag's cell is filmed (px): at the image's centre and at the arena's corner the
    image resolves worst (a lens squeezes or stretches the corners)."""

    centre: float
    worst: float
    corner: str                 # that corner's name, e.g. "north-east"
    side: float                 # the tag plate's side (m): the robot's marker card's length
    plate: float                # the plate's height (m): the tracked plane


def tag_cells(cfg: ScenarioConfig) -> TagCells | None:
    """The tag cell size of a tag scenario's robots as its camera films them, or None for
    colour markers. A world of two robots gives the plate's side and height (as the run's)."""
    if not isinstance(cfg.markers, ArucoMarkers):
        return None
    world = build_world(cfg, 2)
    return _cells(cfg, math.sqrt(world.marker_area), world.marker_height, cfg.camera.height)


def _cells(cfg: ScenarioConfig, side: float, plate: float, camera_height: float) -> TagCells:
    """Cell widths with the camera at `camera_height` (fovy as the scenario's camera has it):
    the floor scale of a camera as high above the marker plane."""
    cam = cfg.camera
    plane = replace(cam, height=camera_height - plate, fovy=cam.fovy_for(cfg.arena))
    corners = [[sx * cfg.arena[0] / 2, sy * cfg.arena[1] / 2] for sx, sy in CORNERS.values()]
    px = plane.px_per_m_at(cfg.arena, np.array([[0.0, 0.0], *corners])) * side / \
        cfg.markers.cells
    worst = int(np.argmin(px[1:]))
    return TagCells(float(px[0]), float(px[1 + worst]), list(CORNERS)[worst], side, plate)


def check_tag_cells(cfg: ScenarioConfig) -> TagCells | None:
    """Refuse, in one line, tags whose cells are filmed narrower than MIN_TAG_CELL_PX anywhere in
    the arena, naming the width and the fixes with their figures; the cell sizes otherwise
    (None for colour markers)."""
    cells = tag_cells(cfg)
    if cells is None or cells.worst >= MIN_TAG_CELL_PX:
        return cells
    grow = MIN_TAG_CELL_PX / cells.worst
    w, h = cfg.camera.resolution
    fixes = [f"raise camera.resolution to {math.ceil(w * grow)} x {math.ceil(h * grow)}"]
    lower = _lower_camera(cfg, cells)
    if lower is not None:
        fixes.append(f"lower the camera to {lower:.2f} m (its fovy kept)")
    fixes.append(f"give the robot a marker card at least {cells.side * grow * 100:.1f} cm long "
                 "(its geom 'marker': the plate's side)")
    markers = cfg.markers
    raise UserError(f"{cfg.name}: the tags' cells are filmed {cells.worst:.2f} px wide at the "
                    f"arena's {cells.corner} corner ({cells.centre:.2f} px at the image's "
                    f"centre), under the {MIN_TAG_CELL_PX:g} px the tag detector reads through "
                    f"the imaging noise ({markers.dictionary}, {markers.cells} cells across a "
                    f"{cells.side * 100:.1f} cm plate); {', '.join(fixes[:-1])}, or "
                    f"{fixes[-1]}", "camera")


def _lower_camera(cfg: ScenarioConfig, cells: TagCells) -> float | None:
    """The camera height (m, to the centimetre) at which a fixed-fovy camera films cells of
    MIN_TAG_CELL_PX and still frames the arena, or None (a fovy that follows the arena keeps
    the floor's scale when the camera is lowered)."""
    if cfg.camera.fovy is None:
        return None
    plate = cells.plate
    high = plate + (cfg.camera.height - plate) * cells.worst / MIN_TAG_CELL_PX
    for _ in range(50):                  # a lens bends the corners: step down until it reads
        height = math.floor(high * 100) / 100
        if height <= plate:
            return None
        if _cells(cfg, cells.side, plate, height).worst >= MIN_TAG_CELL_PX:
            try:
                check_camera(cfg.name, cfg.arena, replace(cfg.camera, height=height))
            except UserError:
                return None
            return height
        high = height - 0.01
    return None


def check_filmed(cfg: ScenarioConfig, n: int) -> None:
    """Everything a tracked run of `n` robots checks before it builds or writes anything: no
    surface or robot part passes for a colour marker, and tags are filmed wide enough."""
    check_rendered_colours(cfg, n)
    check_tag_cells(cfg)
