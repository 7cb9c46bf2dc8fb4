"""The caging mission of seed §2.5.4 (Fig 2.3): a chain that finds a circular object and closes
a ring around it. Pure functions for the geometry and the judge, and `CagingMission`, which
`ChainSim` consults each command tick to change the motion rules.

The text gives no radii, gains or detection rule; ours (`CagingConfig`) are scaled to the
robotarium scenario (spacing d = 8 cm) and documented in docs/explanation/tail-tasks.md:
- the object (radius 4 cm) sits at the arena centre; the boundary of desired final positions is a
  circle of radius d around its centre, where six robots 60° apart are d from each neighbour;
- the team starts along the bottom-left wall; the Head drives toward the middle of the arena
  (its search) until it senses the object within the sensor radius (0.12 m, §2.5.2), then
  circles it counter-clockwise on the boundary (surface following);
- Followers keep the chain rule plus a potential field (Arkin) that pushes them off the object
  when they come within `repulse_reach` of its surface; the Tail gets the same field;
- once Head and Tail face each other near the boundary, within `meet_distance` (`facing`), both
  switch to the Follower rule with each other as second neighbour: the chain is a ring; every
  robot that senses the object then also holds the boundary's distance from it (the radial part
  of the Head's surface following), so the ring settles into a net around it rather than
  sliding off (without it, closed rings slid off the object in 4 of 4 oracle runs).

The Tails that cage through the environment's action alone live in `macrostate_mj.tails.caging`;
the geometry they steer by (`circling_centre`, `circle_velocity`, `offset_for_velocity`) is here.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from macrostate_mj.chain.motion import pull

TRACK_STEPS = 5        # how many of the Head's latest positions the Tail fits a circle to
DETECTION = {"min_arc_deg": 90.0, "max_rms": 0.06, "radius_factor": 2.0}   # loose: estimates

# (observation, info) of one environment step -> the Head's (x, y), or None between its steps
HeadSource = Callable[[dict, dict], np.ndarray | None]


@dataclass(frozen=True)
class CagingConfig:
    centre: tuple[float, float] = (0.0, 0.0)
    object_radius: float = 0.04
    ring_radius: float = 0.08          # the boundary: d, so that six robots are d apart on it
    sensor_radius: float = 0.12        # §2.5.2
    circle_gain: float = 3.0           # radial correction of surface following (1/s)
    repulse_reach: float = 0.04        # the field acts within this distance of the surface
    repulse_gain: float = 0.08         # its speed at the surface (m/s)
    meet_distance: float = 0.11        # Head and Tail this close: the ring closes
    radial_tolerance: float = 0.025    # judge: every robot this near the boundary
    max_gap_deg: float = 100.0         # judge: the largest angular gap between neighbours
    start_corner: tuple[float, float] = (-0.52, -0.26)   # the Tail starts bottom-left
    share_every_s: float | None = 5.0  # the team shares every pose this often (§2.5.3.2: 150
    #                                    steps at 30 Hz); None: only at the start (τ)

    def validate(self, arena: tuple[float, float]) -> None:
        from macrostate_mj.core.errors import UserError

        reach = max(abs(self.centre[0]), abs(self.centre[1])) + self.ring_radius + 0.03
        if self.object_radius <= 0 or self.ring_radius <= self.object_radius or \
                reach > min(arena) / 2:
            raise UserError(f"a caging object of radius {self.object_radius} m with its boundary "
                            f"at {self.ring_radius} m does not fit the {arena[0]} x {arena[1]} m "
                            "arena; choose a smaller object or boundary")


def circle_velocity(p: np.ndarray, centre: np.ndarray, radius: float, speed: float,
                    direction: float, gain: float) -> np.ndarray:
    """Surface following: along the circle of `radius` around `centre` (direction +1
    counter-clockwise, -1 clockwise) with a radial pull onto it (at most twice `speed`, so a
    robot far off the circle spirals in), scaled to `speed`."""
    r = np.asarray(p, float) - np.asarray(centre, float)
    dist = max(float(np.linalg.norm(r)), 1e-9)
    unit = r / dist
    tangent = direction * np.array([-unit[1], unit[0]])
    u = speed * tangent + np.clip(gain * (radius - dist), -2 * speed, 2 * speed) * unit
    return u * speed / max(float(np.linalg.norm(u)), 1e-12)


def repulsion(p: np.ndarray, centre: np.ndarray, surface: float, reach: float,
              gain: float) -> np.ndarray:
    """Arkin's avoid-obstacle field: away from the object, growing linearly from 0 at `reach`
    beyond its surface to `gain` m/s at the surface."""
    r = np.asarray(p, float) - np.asarray(centre, float)
    dist = max(float(np.linalg.norm(r)), 1e-9)
    strength = np.clip((surface + reach - dist) / reach, 0.0, 1.0) * gain
    return strength * r / dist


def winding_number(positions: np.ndarray, point: np.ndarray) -> int:
    """How many times the closed polygon through `positions` (in order) winds around `point`:
    0 when the point lies outside it."""
    rel = np.asarray(positions, float) - np.asarray(point, float)
    ang = np.arctan2(rel[:, 1], rel[:, 0])
    turns = np.diff(np.append(ang, ang[0]))
    turns = (turns + np.pi) % (2 * np.pi) - np.pi
    return int(round(turns.sum() / (2 * np.pi)))


def cage_report(positions: np.ndarray, cfg: CagingConfig) -> dict:
    """The judge: the object is enclosed by the robots' polygon (chain order, closed), every
    robot within `radial_tolerance` of the boundary, the largest angular gap between neighbours
    around the centre below `max_gap_deg`; and the spacing's coefficient of variation."""
    p = np.asarray(positions, float)[:, :2]
    c = np.asarray(cfg.centre, float)
    radial = np.abs(np.linalg.norm(p - c, axis=1) - cfg.ring_radius)
    ang = np.sort(np.arctan2(p[:, 1] - c[1], p[:, 0] - c[0]))
    gaps = np.diff(np.append(ang, ang[0] + 2 * np.pi))
    spacing = np.linalg.norm(p - np.roll(p, -1, axis=0), axis=1)
    report = {"enclosed": winding_number(p, c) != 0,
              "max_radial_error_m": float(radial.max()),
              "max_gap_deg": float(np.degrees(gaps.max())),
              "spacing_cv": float(spacing.std() / spacing.mean())}
    report["caged"] = bool(report["enclosed"] and radial.max() <= cfg.radial_tolerance
                           and report["max_gap_deg"] <= cfg.max_gap_deg)
    return report


def start_poses(cfg: CagingConfig, n: int, spacing: float, rng: np.random.Generator,
                arena: tuple[float, float] | None = None) -> np.ndarray:
    """A straight chain along the bottom-left wall, Tail in the corner (±3 cm), heading right
    within ±10°: where the Head meets the object, and how the chain bends, vary with the draw.
    Head first. Given the `arena`, a chain drawn heading into a wall (about 1 draw in 180 for
    6 GRITSBots in the robotarium) heads the mirrored way instead; every other draw is as
    before."""
    tail = np.asarray(cfg.start_corner, float) + rng.uniform(-0.03, 0.03, 2)
    phi = rng.uniform(-np.radians(10), np.radians(10))

    def line(phi: float) -> np.ndarray:
        xy = tail + np.arange(n)[::-1, None] * spacing * np.array([np.cos(phi), np.sin(phi)])
        return np.column_stack([xy, np.full(n, phi)])

    poses = line(phi)
    if arena is not None and np.any(np.abs(poses[:, :2]) > np.asarray(arena) / 2):
        poses = line(-phi)
    return poses


class CagingMission:
    """Changes the chain's reference velocities each command tick (see the module docstring).
    State: whether the Head has sensed the object, and whether the ring has closed."""

    def __init__(self, cfg: CagingConfig):
        self.cfg = cfg
        self.sensed_at: float | None = None
        self.closed_at: float | None = None

    def reset(self) -> None:
        self.sensed_at = self.closed_at = None

    def facing(self, poses: np.ndarray, cone_deg: float = 60.0) -> bool:
        """Head and Tail meet: both near the boundary, within `meet_distance`, each heading
        toward the other within ±`cone_deg`, and the chain closed through them goes round the
        object (a Tail that meets the Head on the near side, with the object outside the
        chain, does not close it)."""
        cfg, c = self.cfg, np.asarray(self.cfg.centre, float)
        head, tail = poses[0], poses[-1]
        gap = tail[:2] - head[:2]
        if np.linalg.norm(gap) > cfg.meet_distance:
            return False
        near = [abs(np.linalg.norm(q[:2] - c) - cfg.ring_radius) <= 2 * cfg.radial_tolerance
                for q in (head, tail)]
        cone = np.radians(cone_deg)
        bearing = [np.arctan2(gap[1], gap[0]), np.arctan2(-gap[1], -gap[0])]
        turned = [abs(np.angle(np.exp(1j * (q[2] - b)))) <= cone
                  for q, b in zip((head, tail), bearing, strict=True)]
        enclosing = winding_number(poses[:, :2], c) != 0
        return bool(all(near) and all(turned) and enclosing)

    def adjust(self, t: float, poses: np.ndarray, vel: np.ndarray, d: float, k_f: float,
               head_speed: float) -> None:
        """Rewrite `vel` (n, 2) in place for the poses (n, 3) at time t."""
        cfg, p = self.cfg, poses[:, :2]
        c = np.asarray(cfg.centre, float)
        head_gap = float(np.linalg.norm(p[0] - c)) - cfg.object_radius
        if self.sensed_at is None and head_gap <= cfg.sensor_radius:
            self.sensed_at = t
        if self.sensed_at is None:          # search: toward the arena's middle, where it lies
            to_c = c - p[0]
            vel[0] = head_speed * to_c / max(float(np.linalg.norm(to_c)), 1e-9)
        else:
            vel[0] = circle_velocity(p[0], c, cfg.ring_radius, head_speed, 1.0, cfg.circle_gain)
        if self.closed_at is None and self.sensed_at is not None and self.facing(poses):
            self.closed_at = t
        if self.closed_at is not None:                    # a ring: Head and Tail are Followers
            vel[0] = k_f * (pull(p[0], p[1], d) + pull(p[0], p[-1], d))
            vel[-1] = k_f * (pull(p[-1], p[-2], d) + pull(p[-1], p[0], d))
            for i in range(len(p)):          # each senses the object and holds the boundary
                r = p[i] - c
                dist = max(float(np.linalg.norm(r)), 1e-9)
                if dist - cfg.object_radius <= cfg.sensor_radius:
                    vel[i] += cfg.circle_gain * (cfg.ring_radius - dist) * r / dist
        for i in range(len(p)):
            if i > 0 or self.closed_at is not None:
                vel[i] += repulsion(p[i], c, cfg.object_radius, cfg.repulse_reach,
                                    cfg.repulse_gain)


def fit_circle(xy: np.ndarray) -> tuple[np.ndarray, float, float]:
    """Least-squares (Kåsa) circle through points (k, 2): centre, radius, rms residual (m)."""
    xy = np.asarray(xy, float)
    a = np.column_stack([2 * xy, np.ones(len(xy))])
    b = (xy ** 2).sum(axis=1)
    sol, *_ = np.linalg.lstsq(a, b, rcond=None)
    centre = sol[:2]
    radius = float(np.sqrt(max(sol[2] + centre @ centre, 0.0)))
    rms = float(np.sqrt(np.mean((np.linalg.norm(xy - centre, axis=1) - radius) ** 2)))
    return centre, radius, rms


def circling_centre(track: np.ndarray, cfg: CagingConfig, min_arc_deg: float = 120.0,
                    max_rms: float = 0.01, radius_factor: float = 2.0) -> np.ndarray | None:
    """The Tail's detection rule: where the Head (its track (k, 2), true or estimated) is
    circling something of about the boundary's size: the fitted circle's radius within a factor
    `radius_factor` of `ring_radius`, its residual under `max_rms`, and the arc covered at least
    `min_arc_deg`; its centre, or None. A noisy (estimated) track needs looser bounds."""
    track = np.asarray(track, float)
    if len(track) < 5 or not np.all(np.isfinite(track)):
        return None
    centre, radius, rms = fit_circle(track)
    if not (cfg.ring_radius / radius_factor <= radius <= radius_factor * cfg.ring_radius) \
            or rms > max_rms:
        return None
    ang = np.unwrap(np.arctan2(track[:, 1] - centre[1], track[:, 0] - centre[0]))
    return centre if np.degrees(abs(ang[-1] - ang[0])) >= min_arc_deg else None


def offset_for_velocity(u: np.ndarray, tail: np.ndarray, fol: np.ndarray, d: float, k_t: float,
                        bound: float) -> np.ndarray:
    """The destination offset w that makes the Tail rule's reference velocity
    k_t pull(T, F, d) + k_t |F - T| w equal `u` (as `ChainSim.command` applies it), each
    component clipped to ±bound: how a scripted Tail acts through the environment's action."""
    tail, fol = np.asarray(tail, float)[:2], np.asarray(fol, float)[:2]
    gap = max(float(np.linalg.norm(fol - tail)), 1e-3)
    w = (np.asarray(u, float) - k_t * pull(tail, fol, d)) / (k_t * gap)
    return np.clip(w, -bound, bound)
