"""A Head leading two chains, each ending in its own Tail: the team of seed §5.2's future work
("multiple Tail robots deployed in the same team to cooperatively drive other robots to a
destination state"). A line formation has one Tail; a team holds several only if its Head leads
several chains, and each Tail then drives the Followers of its own chain.

Robots are ordered [H, A1, ..., TA, B1, ..., TB] (chain A, the longer, first). Each chain obeys
the §2.3 rules as a line of its own with the shared Head; the robots of both avoid each other.

Caging with this team (`TeamCaging`): the Head drives to the object as in
`chain.caging_mission` and, once it senses it, parks on the boundary instead of circling (a
circling Head would drag both chains round the same way). Both Tails must then wrap their
chains round opposite sides of the object; when they face each other on the far side, the ring
[TA, ..., A1, H, B1, ..., TB] closes and every robot becomes a Follower of its two ring
neighbours, as the one-chain ring does.
`tails.caging.SideTails` is a scripted pair of Tails that does this through the environment's
actions.
"""

from __future__ import annotations

import mujoco
import numpy as np

from macrostate_mj.chain.caging_mission import (
    CagingConfig,
    CagingMission,
    repulsion,
    start_poses,
)
from macrostate_mj.chain.motion import chain_velocities, pulls
from macrostate_mj.chain.sim import ChainSim
from macrostate_mj.chain.world import World
from macrostate_mj.core.errors import UserError

STILL_M = 0.01          # the Head's last TRACK_STEPS positions within this of their mean: parked
SPLAY_DEG = 40.0        # chain B leaves the Head this far from chain A's line at the start


def split_branches(n: int, tails: int) -> list[np.ndarray]:
    """The robots of each chain, Head (0) first: the n - 1 others shared as evenly as possible,
    the longer chains first; every chain at least a Follower and its Tail (ReTLo's module)."""
    if isinstance(tails, bool) or not isinstance(tails, int | np.integer) or tails < 2:
        raise UserError(f"tails must be a whole number of at least 2, got {tails!r}", "tails")
    if n < 1 + 2 * tails:
        raise UserError(f"{tails} chains of a Follower and a Tail each need at least "
                        f"{1 + 2 * tails} robots, got {n}", "robots")
    sizes = [(n - 1) // tails + (i < (n - 1) % tails) for i in range(tails)]
    ends = np.cumsum([1, *sizes])
    return [np.array([0, *range(a, b)]) for a, b in zip(ends[:-1], ends[1:], strict=True)]


def ring_order(branches: list[np.ndarray]) -> np.ndarray:
    """The closed ring of two chains: [TA, ..., A1, H, B1, ..., TB]."""
    a, b = branches
    return np.concatenate([a[::-1], b[1:]])


class BranchedSim(ChainSim):
    """`ChainSim` of a Head leading several chains (`branches`, each Head first); `tail_offset`
    is (chains, 2), one destination offset per Tail (`tails`, their neighbours `neighbours`)."""

    def __init__(self, world: World, branches: list[np.ndarray],
                 data: mujoco.MjData | None = None, mission: CagingMission | None = None):
        super().__init__(world, data=data, mission=mission)
        self.branches = branches
        self.tails = np.array([b[-1] for b in branches])
        self.neighbours = np.array([b[-2] for b in branches])
        self.tail_offset = np.zeros((len(branches), 2))

    def reset(self, rng: np.random.Generator, start: np.ndarray | None = None) -> None:
        super().reset(rng, start)
        self.tail_offset = np.zeros((len(self.branches), 2))

    def reference_velocities(self, poses: np.ndarray) -> np.ndarray:
        cfg, p = self.cfg, poses[:, :2]
        vel = np.zeros_like(p)
        for b in self.branches:          # the Head's row is the same from every chain
            vel[b] = chain_velocities(p[b], self.planner.target, cfg.spacing, cfg.k_f, self.k_t,
                                      followers=cfg.followers)
        vel = self.kept_apart(p, vel)
        gap = np.linalg.norm(p[self.neighbours] - p[self.tails], axis=1)
        vel[self.tails] += self.k_t * gap[:, None] * self.tail_offset
        return vel


def team_start_poses(cfg: CagingConfig, branches: list[np.ndarray], spacing: float,
                     rng: np.random.Generator,
                     arena: tuple[float, float] | None = None) -> np.ndarray:
    """The one-chain start of as many robots (`chain.caging_mission.start_poses`, the same draws and
    the same mirror given the `arena`, so a seed puts the Head where it puts the one-chain
    Head), chain A trailing straight back from the Head along that line, chain B at
    `SPLAY_DEG` from it toward the arena's middle; each robot facing the one ahead."""
    n = int(max(b.max() for b in branches)) + 1
    line = start_poses(cfg, n, spacing, rng, arena)
    head, phi = line[0, :2], line[0, 2]
    out = np.zeros((n, 3))
    out[0] = line[0]
    for b, turn in zip(branches, (0.0, -np.radians(SPLAY_DEG)), strict=True):
        heading = phi + turn
        ahead = np.array([np.cos(heading), np.sin(heading)])
        out[b[1:], :2] = head - np.arange(1, len(b))[:, None] * spacing * ahead
        out[b[1:], 2] = heading
    return out


class TeamCaging(CagingMission):
    """The two-chain caging mission (see the module docstring); `ring` is `ring_order`."""

    def __init__(self, cfg: CagingConfig, ring: np.ndarray):
        super().__init__(cfg)
        self.ring = ring

    def adjust(self, t: float, poses: np.ndarray, vel: np.ndarray, d: float, k_f: float,
               head_speed: float) -> None:
        cfg, p = self.cfg, poses[:, :2]
        c = np.asarray(cfg.centre, float)
        r = p[0] - c
        dist = max(float(np.linalg.norm(r)), 1e-9)
        if self.sensed_at is None and dist - cfg.object_radius <= cfg.sensor_radius:
            self.sensed_at = t
        speed = head_speed if self.sensed_at is None else np.clip(
            cfg.circle_gain * (dist - cfg.ring_radius), -head_speed, head_speed)
        vel[0] = -speed * r / dist           # search toward the middle, then park on the ring
        if self.closed_at is None and self.sensed_at is not None and self.facing(poses[self.ring]):
            self.closed_at = t
        if self.closed_at is not None:       # a ring: everyone a Follower of its ring neighbours
            q = p[self.ring]
            vel[self.ring] = k_f * (pulls(q, np.roll(q, 1, 0), d) + pulls(q, np.roll(q, -1, 0), d))
            rel = p - c
            far = np.maximum(np.linalg.norm(rel, axis=1), 1e-9)
            sensing = far - cfg.object_radius <= cfg.sensor_radius
            vel[sensing] += (cfg.circle_gain * (cfg.ring_radius - far) / far)[sensing, None] * \
                rel[sensing]
        for i in range(len(p)):
            if i > 0 or self.closed_at is not None:
                vel[i] += repulsion(p[i], c, cfg.object_radius, cfg.repulse_reach,
                                    cfg.repulse_gain)
