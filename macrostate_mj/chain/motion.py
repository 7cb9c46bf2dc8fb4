"""Motion rules of the chain (seed §2.3) and their conversion to wheel speeds, as pure functions.

The rules are holonomic reference velocities in the world plane; a nonholonomic robot tracks
them through unicycle kinematics (v, omega), which become wheel angular speeds. Positions are
metres in the world frame, headings radians CCW from +x.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

import numpy as np

from macrostate_mj.core.angles import wrap_angle
from macrostate_mj.core.errors import UserError

if TYPE_CHECKING:
    from macrostate_mj.chain.scene import Obstacle


def head_velocity(p: np.ndarray, target: np.ndarray, gain: float = 1.0) -> np.ndarray:
    """Head rule: p' = gain (T - p), straight at the target, slowing as it arrives."""
    return gain * (np.asarray(target, float) - np.asarray(p, float))


def _norm(v: np.ndarray) -> float:
    """|v| of one vector as `np.linalg.norm` computes it (sqrt of the dot product, so bit for
    bit the same), without its per-call overhead: the control tick calls it per robot."""
    return math.sqrt(v.dot(v))


def pull(p: np.ndarray, q: np.ndarray, d: float, hold: float = 0.0) -> np.ndarray:
    """(|p - q| - d)(q - p): toward q when farther than d, away when nearer (but not within
    `hold` of d: see `pulls`)."""
    return pulls(np.asarray(p, float)[None], np.asarray(q, float)[None], d, hold)[0]


def pulls(p: np.ndarray, q: np.ndarray, d: float, hold: float = 0.0, start: float = 0.0
          ) -> np.ndarray:
    """`pull` of each row (m, 2) of p toward its row of q; each row bit for bit `pull`'s (the
    norms one by one, as `np.linalg.norm` takes them; the rest elementwise). A row less than
    `hold` (m) nearer than d is not pushed away, and one less than `start` farther is not
    pulled: it stays put."""
    diff = np.asarray(q, float) - np.asarray(p, float)
    dist = np.array([_norm(row) for row in diff])
    gap = dist - d
    if hold > 0.0:
        gap = np.where((gap < 0.0) & (gap > -hold), 0.0, gap)
    if start > 0.0:
        gap = np.where((gap > 0.0) & (gap < start), 0.0, gap)
    return gap[:, None] * diff


def follower_velocity(p: np.ndarray, ahead: np.ndarray, behind: np.ndarray, d: float,
                      k_f: float) -> np.ndarray:
    """Follower rule: keep distance d to both neighbours with gain k_f (1 / (m s))."""
    return TwoNeighbours().velocities(*(np.asarray(a, float)[None] for a in (p, ahead, behind)),
                                      d, k_f)[0]


def waiting_follower_velocity(p: np.ndarray, ahead: np.ndarray, behind: np.ndarray, d: float,
                              k_f: float, slack: float) -> np.ndarray:
    """Lab Follower (seed §2.6.2.1): regulate the distance to the robot ahead; regulate the one
    behind only by stopping (not backing up) while it lags more than d + slack."""
    return WaitForBehind(slack).velocities(
        *(np.asarray(a, float)[None] for a in (p, ahead, behind)), d, k_f)[0]


def tail_velocity(p: np.ndarray, ahead: np.ndarray, d: float, k_t: float,
                  hold: float = 0.0, start: float = 0.0) -> np.ndarray:
    """Tail rule: keep distance d to its single neighbour with gain k_t."""
    return k_t * pulls(np.asarray(p, float)[None], np.asarray(ahead, float)[None], d, hold,
                       start)[0]


class FollowerRule(Protocol):
    """How the rear robots turn their neighbours into reference velocities: Followers from
    rows (m, 2) of positions, the robots ahead and the robots behind; the Tail from its own
    position and its one neighbour's."""

    def velocities(self, p: np.ndarray, ahead: np.ndarray, behind: np.ndarray, d: float,
                   k_f: float) -> np.ndarray: ...

    def tail(self, p: np.ndarray, ahead: np.ndarray, d: float, k_t: float) -> np.ndarray: ...


@dataclass(frozen=True)
class TwoNeighbours:
    """Seed §2.3: regulate the distance d to both neighbours."""

    def velocities(self, p: np.ndarray, ahead: np.ndarray, behind: np.ndarray, d: float,
                   k_f: float) -> np.ndarray:
        return k_f * (pulls(p, ahead, d) + pulls(p, behind, d))

    def tail(self, p: np.ndarray, ahead: np.ndarray, d: float, k_t: float) -> np.ndarray:
        return tail_velocity(p, ahead, d, k_t)


@dataclass(frozen=True)
class WaitForBehind:
    """Lab rule (seed §2.6.2.1): follow the robot ahead, wait while the one behind lags more
    than d + slack (m). A rear robot less than `hold` (m) nearer than d to the robot ahead
    stops rather than moves away from it: one that may not reverse would otherwise turn on the
    spot to back off, and with stiff gains a millimetre too close sets a parked chain spinning
    (`hold` = d: it never backs off). One less than `start` (m) farther than d waits too, so
    that it sets off only once the robot ahead has pulled clearly away, at once at the speed
    its gain gives for that gap (the real rear robots' median speed jumps from 1.5 to 6 cm/s
    between gaps of 29 and 31 cm), and a parked chain is not tugged into turning on the
    spot."""

    slack: float
    hold: float = 0.0
    start: float = 0.0

    def __post_init__(self) -> None:
        for name in ("slack", "hold", "start"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise UserError(f"followers.{name} must be a distance >= 0 m, got {value}")

    def velocities(self, p: np.ndarray, ahead: np.ndarray, behind: np.ndarray, d: float,
                   k_f: float) -> np.ndarray:
        lag = np.array([_norm(row) for row in behind - p]) > d + self.slack
        out = k_f * pulls(p, ahead, d, self.hold, self.start)
        out[lag] = 0.0
        return out

    def tail(self, p: np.ndarray, ahead: np.ndarray, d: float, k_t: float) -> np.ndarray:
        return tail_velocity(p, ahead, d, k_t, self.hold, self.start)


def chain_velocities(positions: np.ndarray, head_target: np.ndarray | None, d: float, k_f: float,
                     k_t: float, head_gain: float = 1.0,
                     followers: FollowerRule = TwoNeighbours()) -> np.ndarray:
    """Reference velocities of a whole chain ordered [H, F1, ..., T] (F1 nearest the Head).

    The Head's row is zero when `head_target` is None (a Head driven directly in (v, omega)).
    """
    p = np.asarray(positions, float)
    n = len(p)
    out = np.zeros_like(p)
    if head_target is not None:
        out[0] = head_velocity(p[0], head_target, head_gain)
    if n > 2:
        out[1:n - 1] = followers.velocities(p[1:n - 1], p[:n - 2], p[2:], d, k_f)
    out[n - 1] = followers.tail(p[n - 1], p[n - 2], d, k_t)
    return out


def avoidance_velocities(positions: np.ndarray, radius: float, gain: float) -> np.ndarray:
    """Repulsion from every robot nearer than `radius`, growing linearly to `gain` m/s at
    contact: lets a Head that turns back steer around its own chain instead of pushing it."""
    p = np.asarray(positions, float)
    diff = p[:, None, :] - p[None, :, :]
    dist = np.linalg.norm(diff, axis=2)
    np.fill_diagonal(dist, np.inf)
    push = np.clip((radius - dist) / radius, 0.0, None) * gain
    return np.sum(push[:, :, None] * diff / dist[:, :, None], axis=1)


def steer_around(positions: np.ndarray, vel: np.ndarray, obstacles: tuple[Obstacle, ...],
                 radius: float, gain: float) -> np.ndarray:
    """Reference velocities (n, 2) bent around obstacles nearer than `radius` to a robot's
    centre: the part heading into the obstacle fades out and a repulsion grows (linearly to
    `gain` m/s at its outline), as for robots. What is left slides along the obstacle, so a
    chain drawn round a corner follows its Head around instead of pushing into it."""
    p = np.asarray(positions, float)
    out = np.array(vel, float)
    for ob in obstacles:
        if not ob.within(p, radius):
            continue                # no robot near it: it adds nothing (to the last bit)
        dist, normal = ob.distance(p)
        w = np.clip((radius - dist) / radius, 0.0, 1.0)[:, None]
        into = np.minimum(np.sum(out * normal, axis=1), 0.0)[:, None]
        out += w * (gain * normal - into * normal)
    return out


def path_blocked(positions: np.ndarray, i: int, heading: float, radius: float,
                 cone: float = np.radians(60)) -> bool:
    """Is another robot within `radius` ahead of robot i (inside +-cone of its heading)?"""
    p = np.asarray(positions, float)
    diff = np.delete(p, i, axis=0) - p[i]
    near = np.linalg.norm(diff, axis=1) < radius
    bearing = np.abs(wrap_angle(np.arctan2(diff[:, 1], diff[:, 0]) - heading))
    return bool(np.any(near & (bearing < cone)))


def unicycle_from_holonomic(u: np.ndarray, theta: float, k_omega: float, v_max: float,
                            allow_reverse: bool = True, deadband: float = 0.005
                            ) -> tuple[float, float]:
    """Track a holonomic velocity u with a unicycle: v = |u| cos e, omega = k_omega e.

    e is the angle from the robot's heading to u. With `allow_reverse` a reference behind the
    robot is tracked backwards, turning the rear toward it (no half-turns for small
    corrections); otherwise the robot stops instead of backing up and turns on the spot (the
    lab's followers: fewer high-frequency oscillations, seed §2.6.2.1). Below `deadband` (m/s)
    the robot holds still rather than spinning on the spot. One robot of `unicycle_commands`.
    """
    v, omega = unicycle_commands(np.asarray(u, float)[None], np.array([theta], float), k_omega,
                                 np.array([v_max], float), np.array([allow_reverse]), deadband)
    return float(v[0]), float(omega[0])


def unicycle_commands(u: np.ndarray, theta: np.ndarray, k_omega: float, v_max: np.ndarray,
                      allow_reverse: np.ndarray, deadband: float = 0.005,
                      turn_speed: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """`unicycle_from_holonomic` for n robots at once: u (n, 2), theta, v_max, allow_reverse
    (n,) -> v, omega (n,). Elementwise ufuncs only, so each robot's numbers are bit for bit
    those of the one-robot call (the chain's control tick costs one call, not n).

    `turn_speed` (n,), each in [0, 1]: the share of its speed a robot keeps while it turns
    toward a reference less than 90 degrees off its heading, v = |u| (s + (1 - s) cos e):
    0 is the text's tracking (v = |u| cos e, slowing in every turn), 1 drives through a turn
    at full speed, as the real Head does (`ScenarioConfig.head_turn_speed`)."""
    speed = np.hypot(u[:, 0], u[:, 1])
    still = speed < deadband
    speed = np.minimum(speed, v_max)
    e = wrap_angle(np.arctan2(u[:, 1], u[:, 0]) - theta)
    v = speed * np.cos(e)
    if turn_speed is not None and np.any(turn_speed > 0):
        v = np.where((turn_speed > 0) & (v > 0),
                     speed * (turn_speed + (1 - turn_speed) * np.cos(e)), v)
    back = allow_reverse & (v < 0)
    e = np.where(back, wrap_angle(e + np.pi), e)
    v = np.where(allow_reverse, v, np.maximum(v, 0.0))
    return np.where(still, 0.0, v), np.where(still, 0.0, k_omega * e)


def wheel_speeds(v: float, omega: float, wheel_radius: float, track: float,
                 max_wheel_speed: float) -> tuple[float, float]:
    """Differential drive: (v, omega) -> (left, right) wheel rad/s, scaled down together so
    neither exceeds the motor limit (keeps the commanded curvature when saturating)."""
    left, right = wheel_commands(np.array([v], float), np.array([omega], float), wheel_radius,
                                 track, max_wheel_speed)
    return float(left[0]), float(right[0])


def wheel_commands(v: np.ndarray, omega: np.ndarray, wheel_radius: float, track: float,
                   max_wheel_speed: float) -> tuple[np.ndarray, np.ndarray]:
    """`wheel_speeds` for n robots at once (elementwise, bit for bit the one-robot numbers)."""
    left = (v - omega * track / 2) / wheel_radius
    right = (v + omega * track / 2) / wheel_radius
    peak = np.maximum(np.abs(left), np.abs(right))
    over = peak > max_wheel_speed
    peak = np.where(over, peak, 1.0)
    return (np.where(over, left * max_wheel_speed / peak, left),
            np.where(over, right * max_wheel_speed / peak, right))


def body_twist(wheel_left: float, wheel_right: float, wheel_radius: float,
               track: float) -> tuple[float, float]:
    """Inverse of `wheel_speeds` without saturation: wheel rad/s -> (v, omega)."""
    v = wheel_radius * (wheel_left + wheel_right) / 2
    omega = wheel_radius * (wheel_right - wheel_left) / track
    return v, omega


ROBOT_SIZE_M = 0.11        # Thymio II size that scales the Tail's perturbation σ (seed §3.3)


def draw_tail_offsets(rng: np.random.Generator, sigma: float, shape: tuple[int, ...] = ()
                      ) -> np.ndarray:
    """The Tail's destination perturbation w ~ N(0, (σ · robot size)² I) of §3.3, `shape` of
    them: the RO phase draws one, the SR phase k."""
    return rng.normal(0.0, sigma * ROBOT_SIZE_M, size=(*shape, 2))


def drive_tail(tail: np.ndarray, fol_xy: np.ndarray, offsets: np.ndarray, d: float, k_t: float,
               k_omega: float, v_max: float, allow_reverse: bool, period: float, ticks: int,
               substeps: int = 5, rule: FollowerRule = TwoNeighbours()) -> np.ndarray:
    """Where the Tail (x, y, θ) is after `ticks` command ticks of `period` s toward each
    destination offset (K, 2) (the SRS perturbation), its neighbour held at `fol_xy`: the
    Tail rule (`rule.tail`) plus `k_t |F - T| w` as `ChainSim.command` applies it, tracked through
    `unicycle_from_holonomic`, (v, ω) held over a tick and integrated in `substeps`."""
    out = np.empty((len(offsets), 3))
    fol_xy = np.asarray(fol_xy, float)
    h = period / substeps
    for k, w in enumerate(np.asarray(offsets, float)):
        x, y, th = (float(v) for v in tail)
        for _ in range(ticks):
            p = np.array([x, y])
            u = rule.tail(p, fol_xy, d, k_t) + k_t * np.linalg.norm(fol_xy - p) * w
            v, omega = unicycle_from_holonomic(u, th, k_omega, v_max, allow_reverse)
            for _ in range(substeps):
                x, y = x + v * np.cos(th) * h, y + v * np.sin(th) * h
                th += omega * h
        out[k] = x, y, wrap_angle(th)
    return out
