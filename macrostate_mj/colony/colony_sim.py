"""A simulated Harpegnathos saltator colony in MuJoCo (SPEC §8, seed §4.3.1, §4.5, Fig 4.7).

No raw ant video exists here, so this colony exercises the optical-flow pipeline end to end with
ground truth the seed never had: which ants duel or bite, where and when. About 55 planar ants
(macrostate_mj/assets/mjcf/ant/ant.xml, one MjSpec copy per ant with prefix `antNN_`) live in a
square nest watched by one overhead camera. Each simulated day is one episode: the full MuJoCo
state is reset and every random draw comes from a Generator seeded by (seed, day), so a day's
frames depend only on the seed and the day, never on which other days ran.

Behaviour is a semi-Markov state machine per ant. Stable regime: rest, walk, groom and brief
pairwise antennation. After the gamergates are removed (D0), the aggression level of the day,
`aggression(day)`, adds dueling (two ants face each other, sway back and forth together and
drum their antennae fast) and dominance biting (one ant lunges at the other's head with its
mandibles while the bitten one crouches), and makes walkers faster and more restless. The
controller only asks for velocities and joint angles; contacts keep ants apart and walls keep them
in the nest.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from macrostate_mj.core.angles import wrap_angle
from macrostate_mj.core.errors import UserError
from macrostate_mj.core.paths import ASSETS as MJCF
from macrostate_mj.core.pixels import focal_length, project

ASSETS = MJCF / "ant"
NEST_HALF = 0.075  # m, inner half-width of the nest (walls in scene_nest.xml)
HEAD_TIP = 0.0077  # m, head tip ahead of the thorax centre (site head_tip in ant.xml)
REST, WALK, GROOM, ANTENNATE, DUEL, BITE, BITTEN = range(7)
BEHAVIOURS = ("rest", "walk", "groom", "antennate", "duel", "bite", "bitten")
DAY_MIN, DAY_MAX = -2, 18  # the recorded timeline; D0 is the removal itself, not a day
CTRL_PERIOD = 0.012  # s between controller updates

# Aggression curve (Fig 4.7): zero while the gamergates are present, at its peak on D+1..D+3,
# then an exponential fade that is nearly complete by D+10, leaving a few hostile ants.
PEAK_END, FADE_DAYS, RESIDUAL = 3.0, 2.0, 0.05


def aggression(day: float | np.ndarray) -> float | np.ndarray:
    """Share of peak aggression on `day` (days since removal; ≤ 0 means before it).

    0 before removal; 1 on D+1..D+3; then RESIDUAL + (1 − RESIDUAL)·exp(−(day − 3)/2), which is
    0.26 on D+6, 0.08 on D+10 and 0.05 by D+18: the seed saw the flow weight jump on D+1 and
    return to its stable level by about D+10 although some ants still fought.
    """
    d = np.asarray(day, dtype=float)
    fade = np.exp(-np.clip(d - PEAK_END, 0.0, None) / FADE_DAYS)
    out = np.where(d > 0, RESIDUAL + (1.0 - RESIDUAL) * fade, 0.0)
    return float(out) if out.ndim == 0 else out


@dataclass(frozen=True)
class Regime:
    """Behaviour rates for one aggression level; per-ant rates are per second."""

    solo_p: tuple[float, float, float]  # probability of rest, walk, groom when a bout ends
    solo_s: tuple[float, float, float]  # mean bout length (s) of rest, walk, groom
    speed: float  # walking speed (m/s)
    turn_sd: float  # stationary s.d. of the walking turn rate (rad/s)
    antennate_rate: float
    duel_rate: float
    bite_rate: float


def regime(a: float) -> Regime:
    """Interpolate from the stable colony (a = 0) to peak conflict (a = 1): more walking, faster
    and twistier, and dueling/biting hazards proportional to aggression."""
    return Regime(
        solo_p=(0.55 - 0.25 * a, 0.30 + 0.25 * a, 0.15),
        solo_s=(8.0 - 4.0 * a, 4.0, 3.0),
        speed=0.008 * (1.0 + 0.8 * a),
        turn_sd=1.2 * (1.0 + a),
        antennate_rate=0.012,
        duel_rate=0.014 * a,
        bite_rate=0.006 * a,
    )


DUEL_SWAY_M, DUEL_SWAY_HZ = 0.005, 1.2  # duelers' joint back-and-forth along their axis
PAIR_SECONDS = {ANTENNATE: (0.8, 2.0), DUEL: (4.0, 14.0), BITE: (1.5, 4.0)}  # uniform ranges


def appendage_targets(beh: np.ndarray, t: float, phase: np.ndarray, a: float) -> np.ndarray:
    """Joint targets (n × 5: antenna l, antenna r, mandible l, mandible r, gaster) per behaviour.

    Antenna frequencies: resting 0.3 Hz drift, walking 1.5 Hz sweep, grooming 2 Hz with antennae
    swept back, antennation 2.5 Hz, dueling 7 Hz drumming (the fast back-and-forth of Fig 4.3),
    biting 2.5 Hz mandible snaps while the bitten ant folds its antennae back.
    """
    hz = np.array([0.3, 1.5 * (1 + 0.3 * a), 2.0, 2.5, 7.0, 2.5, 0.2])[beh]
    amp = np.array([0.10, 0.25, 0.25, 0.30, 0.45, 0.20, 0.05])[beh]
    mid = np.array([0.25, 0.20, -0.35, 0.10, 0.20, 0.10, -0.50])[beh]
    s = np.sin(2 * np.pi * hz * t + phase)
    out = np.zeros((beh.size, 5))
    out[:, 0] = mid + amp * s
    out[:, 1] = mid - amp * s  # antiphase: left forward while right back
    bite = beh == BITE
    out[bite, 2:4] = (0.35 + 0.35 * np.sin(2 * np.pi * 2.5 * t + phase[bite]))[:, None]
    groom = beh == GROOM
    out[groom, 2:4] = 0.2 + 0.15 * s[groom, None]
    out[groom, 4] = 0.35 * np.sin(2 * np.pi * 0.5 * t + phase[groom])
    return out


def pair_targets(pos: np.ndarray, yaw: np.ndarray, beh: np.ndarray, partner: np.ndarray,
                 t: float, phase: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Target thorax positions, their velocities, and headings for ants in a pair behaviour.

    Antennating and dueling ants face each other on the line through their thoraxes, head tips a
    few mm apart; duelers also jerk together back and forth along that line (±5 mm at 1.2 Hz, one
    advancing as the other retreats: Fig 4.3's "moving back and forth"), up to 9 mm between two
    frames 0.5 s apart, more than a walker covers at peak agitation (7 mm). With ~25 agitated
    walkers around a few duels, the peak of the flow magnitude falls in a duel or bite box in .31
    of 523 unstable samples, against .20 by chance: duels are often, not always, the strongest
    motion. The sway is a velocity feed-forward; the position term only holds the pair's
    spacing, so the pair's midpoint swings by ±5 mm. A biter aims its head tip at the partner's
    head and lunges (±1.2 mm, 2.5 Hz); the bitten ant stays put. Rows of solo ants are NaN.
    """
    n = pos.shape[0]
    tgt, vel, head = np.full((n, 2), np.nan), np.zeros((n, 2)), np.full(n, np.nan)
    for i in np.flatnonzero(beh >= ANTENNATE):
        j = partner[i]
        if beh[i] == BITTEN:
            tgt[i], head[i] = pos[i], yaw[i]
            continue
        if beh[i] == BITE:
            hj = np.array([math.cos(yaw[j]), math.sin(yaw[j])])
            aim = pos[j] + 0.005 * hj
            u = aim - pos[i]
            u /= max(np.linalg.norm(u), 1e-6)
            w = 2 * np.pi * 2.5
            reach = HEAD_TIP + 0.0017 - 0.0012 * math.sin(w * t + phase[i])
            tgt[i], vel[i] = aim - u * reach, u * 0.0012 * w * math.cos(w * t + phase[i])
            head[i] = math.atan2(u[1], u[0])
            continue
        u = pos[i] - pos[j]
        u /= max(np.linalg.norm(u), 1e-6)
        mid = 0.5 * (pos[i] + pos[j])
        gap, vsway = 0.003, 0.0
        if beh[i] == DUEL:
            w = 2 * np.pi * DUEL_SWAY_HZ
            ph = phase[min(i, j)] + (0.0 if i < j else np.pi)
            gap, vsway = 0.0012, DUEL_SWAY_M * w * math.cos(w * t + ph)
        tgt[i] = mid + u * (HEAD_TIP + gap)
        vel[i] = u * vsway
        head[i] = math.atan2(-u[1], -u[0])
    return tgt, vel, head


@dataclass(frozen=True)
class ColonyConfig:
    """What to simulate; geometry comes from the MJCF files."""

    n_ants: int = 55
    n_prey: int = 0
    fps: float = 15.0
    size: int = 256
    seed: int = 0
    warmup_s: float = 1.0
    max_timestep: float = 0.007  # s; contacts (solref 0.02) and antenna servos stay stable


def build_model(cfg: ColonyConfig):
    """Compile the nest with cfg.n_ants prefixed ant copies and cfg.n_prey passive crickets."""
    import mujoco

    spec = mujoco.MjSpec.from_file(str(ASSETS / "scene_nest.xml"))
    ant = mujoco.MjSpec.from_file(str(ASSETS / "ant.xml"))
    spec.copy_during_attach = True
    for i in range(cfg.n_ants):
        spec.attach(ant, prefix=f"ant{i:02d}_", frame=spec.worldbody.add_frame())
    prey = spec.find_default("prey")
    for k in range(cfg.n_prey):
        body = spec.worldbody.add_body(name=f"prey{k}", pos=[0, 0, 0.003])
        for axis, jtype in (("x", mujoco.mjtJoint.mjJNT_SLIDE), ("y", mujoco.mjtJoint.mjJNT_SLIDE),
                            ("yaw", mujoco.mjtJoint.mjJNT_HINGE)):
            vec = {"x": [1, 0, 0], "y": [0, 1, 0], "yaw": [0, 0, 1]}[axis]
            body.add_joint(prey, name=f"prey{k}_{axis}", type=jtype, axis=vec)
        body.add_geom(prey, name=f"prey{k}_body", fromto=[-0.009, 0, 0, 0.006, 0, 0],
                      size=[0.0028, 0, 0])
        body.add_geom(prey, name=f"prey{k}_head", type=mujoco.mjtGeom.mjGEOM_SPHERE,
                      pos=[0.0085, 0, 0], size=[0.0024, 0, 0])
    steps = max(1, math.ceil(1.0 / (cfg.fps * cfg.max_timestep)))
    spec.option.timestep = 1.0 / (cfg.fps * steps)  # whole physics steps per rendered frame
    return spec.compile()


def segment_gaps(p: np.ndarray, yaw: float, others: np.ndarray, oyaw: np.ndarray) -> np.ndarray:
    """Closest distance between one ant's body axis and several others' (sampled segments)."""
    s = np.linspace(-0.0125, HEAD_TIP, 7)
    a = p + s[:, None] * np.array([math.cos(yaw), math.sin(yaw)])
    b = others[:, None, :] + s[None, :, None] * np.stack([np.cos(oyaw), np.sin(oyaw)], 1)[:, None]
    return np.linalg.norm(a[None, :, None, :] - b[:, None, :, :], axis=-1).min(axis=(1, 2))


def place(n: int, rng: np.random.Generator, half: float, clearance: float = 0.0045,
          tries: int = 4000) -> tuple[np.ndarray, np.ndarray]:
    """Random non-overlapping planar poses (rejection sampling on the body axes)."""
    pos, yaw = np.zeros((n, 2)), np.zeros(n)
    for i in range(n):
        for _ in range(tries):
            p, y = rng.uniform(-half, half, 2), rng.uniform(-np.pi, np.pi)
            if i == 0 or segment_gaps(p, y, pos[:i], yaw[:i]).min() > clearance:
                break
        else:
            raise UserError(f"cannot fit {n} ants in the nest without overlap; use fewer ants",
                            "ants")
        pos[i], yaw[i] = p, y
    return pos, yaw


class Colony:
    """One colony world: reset it to a day, step the behaviours and physics, render frames."""

    def __init__(self, cfg: ColonyConfig) -> None:
        import mujoco

        self.cfg, self.model = cfg, build_model(cfg)
        self.data = mujoco.MjData(self.model)
        m, n = self.model, cfg.n_ants
        self.qx = np.array([m.joint(f"ant{i:02d}_x").qposadr[0] for i in range(n)])  # y, yaw follow
        self.vx = np.array([m.joint(f"ant{i:02d}_x").dofadr[0] for i in range(n)])
        self.qa = np.array([m.joint(f"ant{i:02d}_antenna_l").qposadr[0] for i in range(n)])
        names = ("vx", "vy", "wz", "antenna_l", "antenna_r", "mandible_l", "mandible_r", "gaster")
        self.act = np.array([[m.actuator(f"ant{i:02d}_{a}").id for a in names] for i in range(n)])
        sites = ("head_tip", "antenna_tip_l", "antenna_tip_r", "gaster_tip")
        self.sites = np.array([[m.site(f"ant{i:02d}_{s}").id for s in sites] for i in range(n)])
        self.prey_q = np.array([m.joint(f"prey{k}_x").qposadr[0] for k in range(cfg.n_prey)], int)
        self.steps_per_frame = round(1.0 / (cfg.fps * m.opt.timestep))
        self.ctrl_every = max(1, round(CTRL_PERIOD / m.opt.timestep))
        self.cam = m.camera("overhead").id
        self.day = 0

    # -- episode ---------------------------------------------------------------------------
    def reset(self, day: int) -> None:
        """Full state reset (warm start included, SPEC §9), seeded layout, warm-up steps."""
        import mujoco

        mujoco.mj_resetData(self.model, self.data)
        n, self.day = self.cfg.n_ants, day
        self.rng = np.random.default_rng([self.cfg.seed, day - DAY_MIN])
        self.a = float(aggression(day))
        self.regime = regime(self.a)
        pos, yaw = place(n + self.cfg.n_prey, self.rng, NEST_HALF - 0.012)
        q = self.data.qpos
        q[self.qx], q[self.qx + 1], q[self.qx + 2] = pos[:n, 0], pos[:n, 1], yaw[:n]
        q[self.prey_q], q[self.prey_q + 1] = pos[n:, 0], pos[n:, 1]
        q[self.prey_q + 2] = yaw[n:]
        self.beh = self.rng.choice(3, size=n, p=self.regime.solo_p).astype(int)
        self.timer = self.rng.exponential(np.array(self.regime.solo_s)[self.beh])
        self.partner = np.full(n, -1)
        self.cooldown = np.zeros(n)
        self.turn = np.zeros(n)
        self.phase = self.rng.uniform(0, 2 * np.pi, n)
        mujoco.mj_forward(self.model, self.data)
        for _ in range(round(self.cfg.warmup_s * self.cfg.fps)):
            self.advance_frame()
        self.data.time = 0.0

    @property
    def poses(self) -> tuple[np.ndarray, np.ndarray]:
        q = self.data.qpos
        return np.stack([q[self.qx], q[self.qx + 1]], 1), q[self.qx + 2].copy()

    # -- behaviour -------------------------------------------------------------------------
    def _update_behaviour(self, dt: float) -> None:
        """Advance bout timers; start new solo bouts and pair interactions (seeded draws only)."""
        rg, rng, n = self.regime, self.rng, self.cfg.n_ants
        self.timer -= dt
        self.cooldown -= dt
        ended = np.flatnonzero(self.timer <= 0)
        for i in ended:  # a pair ends for both partners together (they share one timer)
            if self.timer[i] > 0:  # already restarted as the partner of an earlier ant
                continue
            j = self.partner[i]
            for k in (i, j) if j >= 0 else (i,):
                self.beh[k] = rng.choice(3, p=rg.solo_p)
                self.timer[k] = rng.exponential(rg.solo_s[self.beh[k]])
                if j >= 0:  # after an interaction, 2 s before the next one
                    self.partner[k], self.cooldown[k] = -1, 2.0
        rates = np.array([rg.antennate_rate, rg.duel_rate, rg.bite_rate])
        u = rng.random(n)
        pick = rng.random(n) * rates.sum()
        free = (self.beh <= GROOM) & (self.cooldown <= 0)
        pos, _ = self.poses
        for i in np.flatnonzero(free & (u < rates.sum() * dt)):
            cand = np.flatnonzero(free & (np.arange(n) != i))
            if not free[i] or cand.size == 0:
                continue
            dist = np.linalg.norm(pos[cand] - pos[i], axis=1)
            if dist.min() > 0.03:
                continue
            j = cand[dist.argmin()]
            kind = (ANTENNATE, DUEL, BITE)[int(np.searchsorted(np.cumsum(rates), pick[i]))]
            lo, hi = PAIR_SECONDS[kind]
            self.beh[i], self.beh[j] = kind, (BITTEN if kind == BITE else kind)
            self.partner[i], self.partner[j] = j, i
            self.timer[i] = self.timer[j] = rng.uniform(lo, hi)
            free[i] = free[j] = False

    def _control(self, t: float, dt: float) -> None:
        """Turn behaviours into actuator commands: world velocities, yaw rate, joint targets."""
        rg, n = self.regime, self.cfg.n_ants
        pos, yaw = self.poses
        head = np.stack([np.cos(yaw), np.sin(yaw)], 1)
        tau = 0.5  # s, correlation time of the walking turn rate (Ornstein-Uhlenbeck)
        self.turn += (-self.turn * dt / tau
                      + rg.turn_sd * math.sqrt(2 * dt / tau) * self.rng.standard_normal(n))
        walk = self.beh == WALK
        speed = np.where(walk, rg.speed, 0.0)
        wz = np.where(walk, self.turn, 0.0)
        ahead = pos + 0.018 * head  # steer back toward the centre before reaching a wall
        near = walk & (np.abs(ahead).max(axis=1) > NEST_HALF - 0.006)
        want = np.arctan2(-pos[:, 1], -pos[:, 0])
        wz[near] = 4.0 * wrap_angle(want - yaw)[near]
        groom = self.beh == GROOM
        wz[groom] = 0.6 * np.sin(2 * np.pi * 0.8 * t + self.phase[groom])
        vel = head * speed[:, None]
        tgt, tvel, thead = pair_targets(pos, yaw, self.beh, self.partner, t, self.phase)
        paired = ~np.isnan(thead)
        tgt[paired] = np.clip(tgt[paired], -NEST_HALF + 0.004, NEST_HALF - 0.004)
        vel[paired] = tvel[paired] + 10.0 * (tgt[paired] - pos[paired])
        wz[paired] = 8.0 * wrap_angle(thead[paired] - yaw[paired])
        ctrl = self.data.ctrl
        ctrl[self.act[:, 0]], ctrl[self.act[:, 1]], ctrl[self.act[:, 2]] = vel[:, 0], vel[:, 1], wz
        ctrl[self.act[:, 3:].ravel()] = appendage_targets(self.beh, t, self.phase, self.a).ravel()

    def advance_frame(self, record: list[np.ndarray] | None = None) -> None:
        """One rendered frame of physics: behaviour bouts update per frame, control at ~80 Hz
        (fast enough for 7 Hz antenna drumming; Python control per step would cost more than
        the physics). `record` collects the controls of every step (for benchmarks)."""
        import mujoco

        dt = self.model.opt.timestep
        self._update_behaviour(dt * self.steps_per_frame)
        for k in range(self.steps_per_frame):
            if k % self.ctrl_every == 0:
                self._control(self.data.time, dt * self.ctrl_every)
            if record is not None:
                record.append(self.data.ctrl.copy())
            mujoco.mj_step(self.model, self.data)
        if not np.isfinite(self.data.qpos).all():
            raise RuntimeError(f"colony physics diverged on day {self.day} at t={self.data.time}")

    # -- ground truth ----------------------------------------------------------------------
    def events(self) -> list[tuple[str, int, int]]:
        """Current duel and bite pairs as (kind, ant a, ant b), each pair once."""
        out = []
        for i in np.flatnonzero((self.beh == DUEL) | (self.beh == BITE)):
            j = int(self.partner[i])
            if self.beh[i] == BITE or i < j:
                out.append((BEHAVIOURS[self.beh[i]], int(i), j))
        return out

    def event_box(self, a: int, b: int, margin: float = 0.002) -> tuple[float, float, float, float]:
        """Pixel box (x, y, w, h) in edge coordinates (`core.pixels`) around both ants' head,
        antenna and gaster tips, clipped to the frame."""
        pts = self.data.site_xpos[self.sites[[a, b]].ravel()]
        pts = np.concatenate([pts + [dx, dy, 0] for dx in (-margin, margin)
                              for dy in (-margin, margin)])
        focal = focal_length(self.cfg.size, float(self.model.cam_fovy[self.cam]))
        uv = project(pts, self.data.cam_xpos[self.cam], self.data.cam_xmat[self.cam].reshape(3, 3),
                     focal, self.cfg.size, self.cfg.size) + 0.5     # centres -> edges
        x0, y0 = np.clip(uv.min(axis=0), 0, self.cfg.size)
        x1, y1 = np.clip(uv.max(axis=0), 0, self.cfg.size)
        return float(x0), float(y0), float(x1 - x0), float(y1 - y0)

    def run(self, seconds: float, render: set[int] | None = None, renderer=None,
            ) -> Iterator[tuple[np.ndarray | None, list[tuple[str, int, int, tuple]]]]:
        """Yield (frame or None, events with pixel boxes) for each frame of `seconds`.

        Frames whose index is not in `render` (when given) are not rendered, to save CPU time.
        """
        for k in range(int(round(seconds * self.cfg.fps))):
            if k:
                self.advance_frame()
            frame = None
            if renderer is not None and (render is None or k in render):
                renderer.update_scene(self.data, camera=self.cam)
                frame = renderer.render()
            yield frame, [(kind, a, b, self.event_box(a, b)) for kind, a, b in self.events()]


def parse_days(text: str) -> list[int]:
    """'D-2..D+18' (a range, D0 skipped) or 'D-2,D-1,D+5' → sorted unique day numbers."""
    def one(tok: str) -> int:
        tok = tok.strip().upper()
        if not tok.startswith("D") or tok[1:2] not in "+-" or not tok[2:].isdigit() or not tok[2:]:
            raise UserError(f"bad day {tok!r} in days {text!r}; write days like D-2 or D+5",
                            "days")
        d = int(tok[1:])
        if d == 0 or not DAY_MIN <= d <= DAY_MAX:
            raise UserError(f"day {tok} is outside the timeline D-2..D-1, D+1..D+18 "
                            f"(D0 is the removal itself); fix the days", "days")
        return d

    if ".." in text:
        lo, _, hi = text.partition("..")
        a, b = one(lo), one(hi)
        if a > b:
            raise UserError(f"days {text!r} runs backwards; write the earlier day first", "days")
        days = [d for d in range(a, b + 1) if d != 0]
    else:
        days = [one(t) for t in text.split(",") if t.strip()]
    if not days:
        raise UserError(f"days {text!r} names no day; e.g. D-2..D+18 or D-1,D+1", "days")
    return sorted(set(days))


def day_name(day: int) -> str:
    return f"D{day:+d}"
