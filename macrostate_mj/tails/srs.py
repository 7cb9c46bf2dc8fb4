"""SRS's Tail (seed §3.3.1): in random mode it draws k candidate destinations, scores each by
the novelty of the team motion it would lead to, and drives to the policy's pick. `SRSPolicy`
is the SR phase's hook in a collection; `SRSTail` the same choice as a `Tail` of an environment,
once per log step.

Per random-mode log step, from the last `WINDOW` steps of the team's poses (ground truth):
1. k offsets w ~ N(0, σ²I), the RO draw repeated (the RO phase is k = 1 and no scoring);
2. ζ(φ(h′)) hallucinates F's and H's poses at the next log step;
3. for each w the Tail's own pose then, driving toward its destination moved by w with the rule
   and unicycle conversion the robots run (`chain.motion.drive_tail`);
4. each candidate's window (the last WINDOW − 1 real steps and the hallucinated one, in the frame
   of the Tail's candidate pose) scored by the autoencoder: e, the novelty index;
5. the pick: the order statistic of e at the policy's quantile.
Passive mode (every other `alternate` steps) and the first steps of an episode, before a whole
window exists (or, with `track`, while a robot has not been seen yet), behave as the RO phase
does. The team's poses are the truth, or with `track` the overhead tracker's latest.

The novelty models are seen only as `formats.srs_windows.NoveltyScorer`, loaded from the
config's `NoveltySource` in the episode: `estimators` trains them, and is not imported here.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pyarrow as pa

from macrostate_mj.chain.motion import draw_tail_offsets, drive_tail
from macrostate_mj.chain.sim import ChainSim, Tracker
from macrostate_mj.core.errors import UserError
from macrostate_mj.core.frames import frame_of
from macrostate_mj.core.registry import Registry
from macrostate_mj.formats.srs_windows import (
    WINDOW,
    NoveltyScorer,
    NoveltySource,
    features_to_poses,
    module_of,
    window_features,
)

# The pick policies of §3.5.2.1 as the quantile of the novelty e they take. "Q3" and "Q2" are
# read as the upper and lower quartile (the text's "second and third quantile" is ambiguous).
PICKS: Registry[float] = Registry("SRS pick")
for _pick, _quantile in {"max": 1.0, "q3": 0.75, "med": 0.5, "q2": 0.25}.items():
    PICKS.register(_pick)(_quantile)


def check_srs(pick: str, k: int, sigma: float) -> None:
    """Refuse a pick, candidate count or σ the Tail cannot use, before anything is collected."""
    PICKS[pick]                 # an unknown pick is refused, naming the choices
    if k < 2:
        raise UserError(f"--k must be at least 2 candidates, got {k}")
    if sigma < 0:
        raise UserError(f"--sigma must be non-negative, got {sigma}")


def pick_index(e: np.ndarray, quantile: float) -> int:
    """The candidate at `quantile` of e: the order statistic floor(q (k − 1)) (ties keep the
    draw order); max is the largest, med with an even k the lower of the two middle ones."""
    order = np.argsort(e, kind="stable")
    return int(order[int(np.floor(quantile * (len(e) - 1) + 1e-9))])


@dataclass(frozen=True)
class SRSConfig:
    """The SR phase's policy: a `collectors` policy config (`build` makes its hook)."""

    model: NoveltySource       # the novelty models; which ones is part of the collection's plan
    pick: str = "max"
    k: int = 30
    sigma: float = 0.75        # fraction of the robot size, as in the RO phase
    alternate: int = 6
    track: bool = False        # act on the tracker's poses rather than the truth
    name: str = field(default="srs", init=False)

    def __post_init__(self) -> None:
        check_srs(self.pick, self.k, self.sigma)

    def build(self, rng: np.random.Generator, tracker: Tracker | None = None) -> SRSPolicy:
        if self.track and tracker is None:
            raise UserError("an SRS Tail with track=True needs the episode's tracker")
        return SRSPolicy(self, self.model.load(), rng, tracker if self.track else None)


class SRSPolicy:
    """A periodic hook, one call per log step, setting the simulation's Tail offset; keeps per
    scored step the candidates' e and the pick (`records`)."""

    def __init__(self, cfg: SRSConfig, model: NoveltyScorer, rng: np.random.Generator,
                 tracker: Tracker | None = None):
        self.cfg, self.model, self.rng, self.tracker = cfg, model, rng, tracker
        self.step = 0
        self._history: list[np.ndarray] = []
        self._rows: dict[str, list] = {"t": [], "e": [], "offsets": [], "pick": []}

    def __call__(self, sim: ChainSim) -> None:
        sim.tail_offset = self.choose(sim)

    def choose(self, sim: ChainSim) -> np.ndarray:
        """This log step's destination offset (2,) m, from the team's poses in `sim`."""
        seen = sim.poses if self.tracker is None else self.tracker.latest.copy()
        self._history = [*self._history[-(WINDOW - 1):], seen]
        random_mode = (self.step // self.cfg.alternate) % 2 == 0
        self.step += 1
        if not random_mode:
            return np.zeros(2)
        if len(self._history) < WINDOW or not np.isfinite(self._history).all():
            return draw_tail_offsets(self.rng, self.cfg.sigma)
        offsets = draw_tail_offsets(self.rng, self.cfg.sigma, (self.cfg.k,))
        e = self.scores(sim, np.array(self._history), offsets)
        pick = pick_index(e, PICKS[self.cfg.pick])
        for key, value in (("t", sim.time), ("e", e), ("offsets", offsets), ("pick", pick)):
            self._rows[key].append(value)
        return offsets[pick]

    def scores(self, sim: ChainSim, history: np.ndarray, offsets: np.ndarray) -> np.ndarray:
        """e of each candidate offset (K, 2) from the team's last WINDOW poses (WINDOW, n, 3)."""
        tail, fol, head = module_of(history)
        window = window_features(tail, fol, head)
        nxt = self.model.predict_next(window[None])[0]
        origin, alpha = frame_of(tail[-1, :2], fol[-1, :2])
        fol_next, head_next = features_to_poses(nxt, origin, alpha)
        cfg = sim.cfg
        ticks = int(round(cfg.command_hz / cfg.log_hz))
        tails = drive_tail(tail[-1], fol[-1, :2], offsets, cfg.spacing, sim.k_t, cfg.k_omega,
                           cfg.chain_speed, cfg.allow_reverse, 1 / cfg.command_hz, ticks,
                           rule=cfg.followers)
        k = len(offsets)
        fols = np.broadcast_to(np.concatenate([fol[1:], fol_next[None]]), (k, WINDOW, 3))
        heads = np.broadcast_to(np.concatenate([head[1:], head_next[None]]), (k, WINDOW, 3))
        cand_tails = np.broadcast_to(tails[:, None, :], (k, WINDOW, 3))
        return self.model.novelty(window_features(cand_tails, fols, heads))

    def records(self) -> pa.Table | None:
        """One row per scored step: time, the k candidates' offsets (m) and e, the pick."""
        rows = self._rows
        return pa.table({"t": pa.array(rows["t"], pa.float64()),
                         "offsets": pa.array([o.ravel().tolist() for o in rows["offsets"]],
                                             pa.list_(pa.float64())),
                         "e": pa.array([e.tolist() for e in rows["e"]], pa.list_(pa.float64())),
                         "pick": pa.array(rows["pick"], pa.int32())})


class SRSTail:
    """SRS's Tail (§3.3.1) with a pick policy (SRS-Med: the median novelty), its SR phase's
    choice each log step, held between them. Like the SR phase that collects data, it reads the
    whole team's true poses (`policy` scores candidates by what the Head and Follower would
    do): privileged, where the other Tails see only their neighbour."""

    def __init__(self, sim: ChainSim, every: int, policy: SRSPolicy, bound: float):
        self.sim, self.every, self.policy, self.bound = sim, every, policy, bound
        self.step = 0
        self.offset = np.zeros(2, np.float32)

    def act(self, obs: dict, info: dict) -> np.ndarray:
        if self.step % self.every == 0:
            self.offset = np.clip(self.policy.choose(self.sim), -self.bound,
                                  self.bound).astype(np.float32)
        self.step += 1
        return self.offset
