"""Head planners: where the Head goes next. Each draws only from the Generator it is given.

- `GridPlanner`  Psi of seed §2.6.2.2 (lab): waypoints in cells ahead of the last two visited.
- `CellPlanner`  seed §3.4 (webots): a new nearby cell-centre waypoint whenever a cell is entered.
- `PresetPlanner` seed §2.5.2.1 (robotarium): the Head drives one of five preset (v, omega).
- `FixedWaypoint` one scripted target (tests, demonstrations).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from macrostate_mj.chain.scene import Obstacle, blocked
from macrostate_mj.core.angles import wrap_angle
from macrostate_mj.core.errors import UserError

# Head (v, omega) presets of the robotarium scenario: straight, two gentle and two tighter
# curves (radii 0.3 and 0.15 m, wider than a 6-robot chain is long, so the Head never circles
# onto its own Tail).
ROBOTARIUM_HEAD_PRESETS: tuple[tuple[float, float], ...] = (
    (0.03, 0.0), (0.03, 0.1), (0.03, -0.1), (0.03, 0.2), (0.03, -0.2),
)


@dataclass
class Grid:
    """A cols x rows grid laid over the arena (origin at its centre, x along the long side)."""

    arena: tuple[float, float]
    shape: tuple[int, int]

    def __post_init__(self) -> None:
        if len(self.shape) != 2 or min(self.shape) < 1:
            raise UserError(f"planner.grid must be two whole numbers of cells, each at least 1, "
                            f"got {list(self.shape)}", "grid")

    @property
    def cell_size(self) -> np.ndarray:
        return np.array(self.arena) / np.array(self.shape)

    def cell_of(self, p: np.ndarray) -> int:
        ij = np.floor((np.asarray(p[:2]) + np.array(self.arena) / 2) / self.cell_size).astype(int)
        ij = np.clip(ij, 0, np.array(self.shape) - 1)
        return int(ij[1] * self.shape[0] + ij[0])

    def cell_origin(self, c: int) -> np.ndarray:
        """Lower-left corner of cell c."""
        return np.array([c % self.shape[0], c // self.shape[0]]) * self.cell_size \
            - np.array(self.arena) / 2

    def centre(self, c: int) -> np.ndarray:
        return self.cell_origin(c) + self.cell_size / 2

    def adjacent(self, a: int, b: int) -> bool:
        """8-connected adjacency; a cell is not adjacent to itself."""
        if a < 0 or b < 0 or a == b:
            return False
        (ay, ax), (by, bx) = divmod(a, self.shape[0]), divmod(b, self.shape[0])
        return max(abs(ax - bx), abs(ay - by)) == 1

    def neighbours(self, c: int) -> list[int]:
        return [i for i in range(self.shape[0] * self.shape[1]) if self.adjacent(c, i)]


def psi_candidates(grid: Grid, latest: int, earlier: int) -> list[int]:
    """C = {c_i | A(M[0], i) and not A(M[1], i) and i != M[1]}, falling back to the neighbours
    of M[0] other than M[1] when that set is empty (in corners)."""
    near = grid.neighbours(latest)
    cands = [i for i in near if not grid.adjacent(earlier, i) and i != earlier]
    return cands or [i for i in near if i != earlier]


@dataclass
class GridPlanner:
    """Psi: random waypoints ahead of the Head; memory M = [latest cell, earlier cell].

    A waypoint not reached within `timeout` seconds (blocked by the Head's own chain, whose
    robots it steers around) counts as reached, so the team never deadlocks. Cells whose
    centre lies within `margin` of an obstacle are never chosen, nor points that do. With
    `max_turn` under 180 (degrees) a waypoint more than that off the Head's heading is drawn
    again (up to `REDRAWS` times, then the least turn drawn is kept): Psi alone may send the
    Head back into its own chain, which the real chains never show (their spacing stays
    above 27 cm; docs: decisions/sysid)."""

    REDRAWS = 20

    grid: Grid
    margin: float
    reach_radius: float
    timeout: float = 20.0
    max_turn: float = 180.0
    memory: list[int] = field(default_factory=lambda: [-1, -1])
    target: np.ndarray | None = None
    twist: tuple[float, float] | None = None
    _drawn_at: float = 0.0
    obstacles: tuple[Obstacle, ...] = ()

    def reset(self, head_pose: np.ndarray, rng: np.random.Generator) -> None:
        # Pretend the Head came from the cell behind it, so its first waypoint lies ahead.
        behind = head_pose[:2] - self.grid.cell_size * np.array([np.cos(head_pose[2]),
                                                                np.sin(head_pose[2])])
        self.memory = [self.grid.cell_of(head_pose), self.grid.cell_of(behind)]
        self.target, self._drawn_at = self._draw(rng), 0.0

    def update(self, head_pose: np.ndarray, t: float, rng: np.random.Generator) -> None:
        reached = np.linalg.norm(head_pose[:2] - self.target) < self.reach_radius
        if reached or t - self._drawn_at > self.timeout:
            self.memory = [self.grid.cell_of(self.target), self.memory[0]]
            self.target, self._drawn_at = self._ahead(head_pose, rng), t

    def _ahead(self, head_pose: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """The next waypoint: Psi's draw, redrawn while it lies more than `max_turn` off the
        Head's heading (no redraw, so no extra draw, at 180)."""
        best, least = None, np.inf
        for _ in range(self.REDRAWS if self.max_turn < 180.0 else 1):
            p = self._draw(rng)
            off = p - head_pose[:2]
            turn = abs(float(wrap_angle(np.arctan2(off[1], off[0]) - head_pose[2])))
            if turn < least:
                best, least = p, turn
            if np.degrees(turn) <= self.max_turn:
                break
        return best

    def _draw(self, rng: np.random.Generator) -> np.ndarray:
        cells = psi_candidates(self.grid, *self.memory)
        half = np.array(self.grid.arena) / 2 - self.margin
        if self.obstacles:      # (without obstacles the draws are exactly as before)
            cells = _free_cells(self.grid, cells, half, self.obstacles, self.margin) or \
                _free_cells(self.grid, self.grid.neighbours(self.memory[0]), half,
                            self.obstacles, self.margin) or \
                _free_cells(self.grid, range(int(np.prod(self.grid.shape))), half,
                            self.obstacles, self.margin) or cells
        c = cells[rng.integers(len(cells))]
        p = np.clip(self.grid.cell_origin(c) + rng.random(2) * self.grid.cell_size, -half, half)
        for _ in range(20 if self.obstacles else 0):
            if not blocked(self.obstacles, p, self.margin)[0]:
                return p
            p = np.clip(self.grid.cell_origin(c) + rng.random(2) * self.grid.cell_size,
                        -half, half)
        return np.clip(self.grid.centre(c), -half, half) if self.obstacles else p


def _free_cells(grid: Grid, cells: object, half: np.ndarray, obstacles: tuple[Obstacle, ...],
                margin: float) -> list[int]:
    """Those of `cells` whose (margin-clipped) centre is farther than `margin` from every
    obstacle."""
    cells = list(cells)
    if not cells:
        return []
    centres = np.clip([grid.centre(c) for c in cells], -half, half)
    return [c for c, hit in zip(cells, blocked(obstacles, centres, margin), strict=True)
            if not hit]


@dataclass
class CellPlanner:
    """Webots study: whenever the Head enters a new cell, aim at the centre of a random
    neighbouring cell (not the one just left, so the Head keeps moving on); redraw after
    `timeout` seconds in one cell (a Head blocked by its own chain). Cells whose centre lies
    within `margin` of an obstacle are never chosen."""

    grid: Grid
    margin: float
    timeout: float = 20.0
    cell: int = -1
    previous: int = -1
    target: np.ndarray | None = None
    twist: tuple[float, float] | None = None
    _drawn_at: float = 0.0
    obstacles: tuple[Obstacle, ...] = ()

    def reset(self, head_pose: np.ndarray, rng: np.random.Generator) -> None:
        self.cell, self.previous = self.grid.cell_of(head_pose), -1
        self.target, self._drawn_at = self._draw(rng), 0.0

    def update(self, head_pose: np.ndarray, t: float, rng: np.random.Generator) -> None:
        c = self.grid.cell_of(head_pose)
        if c != self.cell or t - self._drawn_at > self.timeout:
            self.previous, self.cell = self.cell, c
            self.target, self._drawn_at = self._draw(rng), t

    def _draw(self, rng: np.random.Generator) -> np.ndarray:
        half = np.array(self.grid.arena) / 2 - self.margin
        cells = [i for i in self.grid.neighbours(self.cell) if i != self.previous
                 and np.all(np.abs(self.grid.centre(i)) <= half)]
        if self.obstacles:      # boxed in: back the way it came, or anywhere free
            cells = _free_cells(self.grid, cells, half, self.obstacles, self.margin) or \
                _free_cells(self.grid, [i for i in self.grid.neighbours(self.cell)
                                        if np.all(np.abs(self.grid.centre(i)) <= half)],
                            half, self.obstacles, self.margin) or \
                _free_cells(self.grid, [i for i in range(int(np.prod(self.grid.shape)))
                                        if np.all(np.abs(self.grid.centre(i)) <= half)],
                            half, self.obstacles, self.margin) or cells
        return self.grid.centre(cells[rng.integers(len(cells))])


@dataclass
class PresetPlanner:
    """Robotarium Head: hold a preset (v, omega) for `hold` seconds, then draw another. Near a
    wall the Head turns on the spot at `wall_turn` rad/s until it faces within 60 degrees of
    the arena centre, so it never grinds along a wall; within `margin` of an obstacle, alike
    until it faces within 60 degrees of straight away from it."""

    arena: tuple[float, float]
    margin: float
    hold: float = 4.0
    wall_turn: float = 1.0
    presets: tuple[tuple[float, float], ...] = ROBOTARIUM_HEAD_PRESETS
    target: np.ndarray | None = None
    twist: tuple[float, float] | None = None
    _next_switch: float = 0.0
    obstacles: tuple[Obstacle, ...] = ()

    def reset(self, head_pose: np.ndarray, rng: np.random.Generator) -> None:
        self._next_switch = 0.0
        self.update(head_pose, 0.0, rng)

    def update(self, head_pose: np.ndarray, t: float, rng: np.random.Generator) -> None:
        if t >= self._next_switch:
            self.twist = self.presets[rng.integers(len(self.presets))]
            self._next_switch = t + self.hold
        half = np.array(self.arena) / 2 - self.margin
        if np.any(np.abs(head_pose[:2]) > half):
            to_centre = wrap_angle(np.arctan2(-head_pose[1], -head_pose[0]) - head_pose[2])
            if abs(to_centre) > np.radians(60):
                self.twist = (0.0, float(np.sign(to_centre) * self.wall_turn))
            else:
                self.twist = self.presets[0]
        for ob in self.obstacles:
            dist, normal = ob.distance(head_pose[:2])
            if dist[0] < self.margin:
                away = wrap_angle(np.arctan2(normal[0, 1], normal[0, 0]) - head_pose[2])
                if abs(away) > np.radians(60):
                    self.twist = (0.0, float(np.sign(away) * self.wall_turn))
                else:
                    self.twist = self.presets[0]


@dataclass
class FixedWaypoint:
    """Drive the Head to one point and stay there (tests, scripted demonstrations)."""

    point: tuple[float, float]
    target: np.ndarray | None = None
    twist: tuple[float, float] | None = None

    def reset(self, head_pose: np.ndarray, rng: np.random.Generator) -> None:
        self.target = np.array(self.point, float)

    def update(self, head_pose: np.ndarray, t: float, rng: np.random.Generator) -> None:
        pass


Planner = GridPlanner | CellPlanner | PresetPlanner | FixedWaypoint


class PlannerSpec(Protocol):
    """What a scenario names as its Head planner: builds a fresh planner for one world."""

    def build(self, arena: tuple[float, float], margin: float, reach_radius: float,
              obstacles: tuple[Obstacle, ...] = ()) -> Planner:
        ...


@dataclass(frozen=True)
class PsiGrid:
    """Psi on a cols x rows grid (lab, seed §2.6.2.2); `max_turn` (degrees, up to 180: no
    limit) keeps the Head's next waypoint within that turn of its heading."""

    grid: tuple[int, int]
    max_turn: float = 180.0

    def __post_init__(self) -> None:
        Grid((1.0, 1.0), self.grid)          # refused when read, not at the first waypoint
        if not (isinstance(self.max_turn, int | float) and 0 < self.max_turn <= 180):
            raise UserError(f"planner.max_turn must be an angle in (0, 180] degrees, got "
                            f"{self.max_turn!r}")

    def build(self, arena: tuple[float, float], margin: float, reach_radius: float,
              obstacles: tuple[Obstacle, ...] = ()) -> Planner:
        return GridPlanner(Grid(arena, self.grid), margin, reach_radius, obstacles=obstacles,
                           max_turn=self.max_turn)


@dataclass(frozen=True)
class CellWalk:
    """A new neighbouring cell centre whenever the Head enters a cell (webots, seed §3.4)."""

    grid: tuple[int, int]

    def __post_init__(self) -> None:
        Grid((1.0, 1.0), self.grid)

    def build(self, arena: tuple[float, float], margin: float, reach_radius: float,
              obstacles: tuple[Obstacle, ...] = ()) -> Planner:
        return CellPlanner(Grid(arena, self.grid), margin, obstacles=obstacles)


@dataclass(frozen=True)
class PresetTwists:
    """The Head drives preset (v, omega) pairs (robotarium, seed §2.5.2.1)."""

    presets: tuple[tuple[float, float], ...] = ROBOTARIUM_HEAD_PRESETS

    def build(self, arena: tuple[float, float], margin: float, reach_radius: float,
              obstacles: tuple[Obstacle, ...] = ()) -> Planner:
        return PresetPlanner(arena, margin, presets=self.presets, obstacles=obstacles)


@dataclass(frozen=True)
class Park:
    """The Head drives to `point` (m, world) and stays there, the chain lining up behind it:
    a parked team, e.g. beside an obstacle, to check that a lab tracks robots standing still
    where the camera's view is tightest (`soak --track`)."""

    point: tuple[float, float]

    def __post_init__(self) -> None:
        if not (len(self.point) == 2 and all(isinstance(v, int | float) and math.isfinite(v)
                                             for v in self.point)):
            raise UserError(f"planner.point must be [x, y] in metres, got {self.point!r}")

    def build(self, arena: tuple[float, float], margin: float, reach_radius: float,
              obstacles: tuple[Obstacle, ...] = ()) -> Planner:
        half = np.asarray(arena, float) / 2 - margin
        if np.any(np.abs(self.point) > half):
            raise UserError(f"planner.point {list(self.point)} lies outside the "
                            f"{arena[0]:g} x {arena[1]:g} m arena less its margin "
                            f"({margin:g} m); move it inside")
        inside = [i for i, ob in enumerate(obstacles)
                  if ob.distance(np.array([self.point]))[0][0] < reach_radius]
        if inside:
            raise UserError(f"planner.point {list(self.point)} lies on or against "
                            f"arena.obstacles[{inside[0]}] (within the reach radius, "
                            f"{reach_radius:g} m); park beside it, not in it")
        return FixedWaypoint(self.point)
