"""Caging Tails (seed §2.5.4, §5.2): the scripted Tail that encircles the object the Head
circles, the pair of Tails that wrap a two-chain team round it, and where they get the Head's
position (`HeadSource`): the truth (`oracle_source`) or a live estimator (`LiveHeadSource`)."""

from __future__ import annotations

from typing import Protocol

import numpy as np

from macrostate_mj.chain.caging_mission import (
    DETECTION,
    TRACK_STEPS,
    CagingConfig,
    HeadSource,
    circle_velocity,
    circling_centre,
    offset_for_velocity,
)
from macrostate_mj.chain.scenario import ScenarioConfig
from macrostate_mj.chain.sim import ChainSim
from macrostate_mj.chain.team import STILL_M


class CagingTail(Protocol):
    """A Tail of a caging episode: a `Tail` that also says when it found the Head circling
    (s, if it did) and where it believes the Head is."""

    detected_at: float | None

    @property
    def head_estimate(self) -> np.ndarray | None: ...

    def act(self, obs: dict, info: dict) -> np.ndarray: ...


class ScriptedTail:
    """A scripted Tail: watch the Head's track (one position per head-source step); once it
    circles, encircle clockwise: around the mean centre of every circle found so far (an estimated
    track gives a new, noisy fit at most steps) until its own sensor finds the object, then
    around the object it senses (and remembers). It acts through the environment's action (a
    destination offset within ±`bound`), given the scenario, the Tail rule's gain `k_t` and
    the caging geometry."""

    def __init__(self, scenario: ScenarioConfig, k_t: float, caging: CagingConfig,
                 bound: float, head_source: HeadSource):
        self.scenario, self.k_t, self.caging = scenario, k_t, caging
        self.bound = bound
        self.head_source = head_source
        self.track: list[np.ndarray] = []
        self.found: list[np.ndarray] = []          # the centres of the circles found
        self.sensed: np.ndarray | None = None      # the object's centre, once sensed
        self.detected_at: float | None = None

    @property
    def centre(self) -> np.ndarray | None:
        """Where the Tail encircles: the sensed object, else the circles' mean centre."""
        if self.sensed is not None or not self.found:
            return self.sensed
        return np.mean(self.found, axis=0)

    @property
    def head_estimate(self) -> np.ndarray | None:
        """The Head's latest position as the Tail has it."""
        return self.track[-1] if self.track else None

    def act(self, obs: dict, info: dict) -> np.ndarray:
        """The action for the step whose observation and info are `obs`, `info` (time `t`)."""
        t = info["t"]
        head = self.head_source(obs, info)
        if head is not None:
            self.track = [*self.track[-(TRACK_STEPS - 1):], head]
            found = (circling_centre(np.array(self.track), self.caging, **DETECTION)
                     if len(self.track) == TRACK_STEPS and self.sensed is None else None)
            if found is not None:
                self.found.append(found)
                self.detected_at = self.detected_at or t
        tail, fol = obs["tail"][-1], obs["neighbour"][-1]
        if self.found and obs["object"][2] > 0:
            self.sensed = tail[:2] + obs["object"][:2]
        if self.centre is None:
            return np.zeros(2, np.float32)
        u = circle_velocity(tail[:2], self.centre, self.caging.ring_radius,
                            self.scenario.chain_speed, -1.0, self.caging.circle_gain)
        w = offset_for_velocity(u, tail, fol, self.scenario.spacing, self.k_t, self.bound)
        return w.astype(np.float32)


class SideTails:
    """Two scripted Tails that cooperate (see the module docstring). Both watch the Head (one
    position per head-source step); once it has parked (its last `TRACK_STEPS` positions within
    `STILL_M` of their mean), they place the object one boundary radius beyond it along its
    approach, and take opposite sides together: the Tail to the left of the Head's line of
    approach wraps clockwise, the other counter-clockwise, so the chains never cross and meet
    on the far side. The object's centre is shared: once either Tail's own sensor has it, both
    encircle the sensed centre. Actions are destination offsets within ±`bound`. The head
    source reads the observations of Tail `seer` (where an estimator runs, it runs on that
    Tail; the other is told the Head's position, as the object's centre is shared)."""

    def __init__(self, scenario: ScenarioConfig, k_t: float, caging: CagingConfig,
                 bound: float, head_source: HeadSource, seer: int = 0):
        self.scenario, self.k_t, self.caging, self.bound = scenario, k_t, caging, bound
        self.head_source, self.seer = head_source, seer
        self.track: list[np.ndarray] = []
        self.centre: np.ndarray | None = None
        self.sensed = False
        self.directions: np.ndarray | None = None
        self.detected_at: float | None = None

    @property
    def head_estimate(self) -> np.ndarray | None:
        return self.track[-1] if self.track else None

    def act(self, obs: list[dict], info: dict) -> list[np.ndarray]:
        """The two Tails' actions for their observations `obs` (chain A's first), at the time
        `info["t"]`."""
        t = info["t"]
        head = self.head_source(obs[self.seer], info)
        if head is not None:
            self.track.append(head)
            if self.centre is None and self._parked():
                self._decide(np.array([o["tail"][-1, :2] for o in obs]))
                self.detected_at = t
        if self.centre is not None and not self.sensed:
            seen = [o["tail"][-1, :2] + o["object"][:2] for o in obs if o["object"][2] > 0]
            if seen:
                self.centre, self.sensed = np.mean(seen, axis=0), True
        if self.centre is None:
            return [np.zeros(2, np.float32) for _ in obs]
        return [self._encircle(o, s) for o, s in zip(obs, self.directions, strict=True)]

    def _parked(self) -> bool:
        last = np.array(self.track[-TRACK_STEPS:])
        return len(last) == TRACK_STEPS and bool(
            np.linalg.norm(last - last.mean(axis=0), axis=1).max() <= STILL_M)

    def _decide(self, tails: np.ndarray) -> None:
        """Where the object lies and who goes which way."""
        head = self.track[-1]
        moved = [p for p in self.track if np.linalg.norm(head - p) > 2 * STILL_M]
        approach = head - (moved[-1] if moved else self.track[0])
        approach = approach / max(float(np.linalg.norm(approach)), 1e-9)
        self.centre = head + self.caging.ring_radius * approach
        rel = tails - head
        left = approach[0] * rel[:, 1] - approach[1] * rel[:, 0]
        self.directions = np.where(np.arange(2) == np.argmax(left), -1.0, 1.0)

    def _encircle(self, obs: dict, direction: float) -> np.ndarray:
        tail, fol = obs["tail"][-1], obs["neighbour"][-1]
        u = circle_velocity(tail[:2], self.centre, self.caging.ring_radius,
                            self.scenario.chain_speed, direction, self.caging.circle_gain)
        w = offset_for_velocity(u, tail, fol, self.scenario.spacing, self.k_t, self.bound)
        return w.astype(np.float32)


def oracle_source(sim: ChainSim, stride: int) -> HeadSource:
    """The Head's true position every `stride` ticks (privileged, no lag): the upper bound of
    any estimator's head source."""
    ticks = [-1]

    def source(_obs: dict, _info: dict) -> np.ndarray | None:
        ticks[0] += 1
        return sim.poses[0, :2].copy() if ticks[0] % stride == 0 else None
    return source


class OnlineEstimator(Protocol):
    """`estimators.retlo.online.OnlineChain`'s interface (poses Tail first)."""

    def start(self, poses: np.ndarray) -> None: ...

    def observe(self, sensed: np.ndarray) -> None: ...

    def share(self, poses: np.ndarray) -> None: ...

    @property
    def head(self) -> tuple[int, np.ndarray]: ...


class LiveHeadSource:
    """The Head's position as the Tail's live estimator (`chain`, e.g. ReTLo's `OnlineChain`) has
    it after each of its steps (every `stride` ticks; lagging n - 2 steps), from the Tail's
    observations and the poses the team shares (at τ: `team_at_start`, Head first, and in the
    step info's `team`); None between steps. A `chain.caging_mission.HeadSource`. In a team of
    several chains (`chain.team`), `robots` are the team's rows of this Tail's chain, Head first:
    the
    estimator sees only those of what the team shares."""

    def __init__(self, chain: OnlineEstimator, team_at_start: np.ndarray, stride: int,
                 robots: np.ndarray | None = None):
        self.chain, self.stride = chain, stride
        self.robots = slice(None) if robots is None else np.asarray(robots)
        chain.start(team_at_start[self.robots][::-1])            # Tail first
        self._tick = -1          # the observation of tick k comes with the info of tick k

    def __call__(self, obs: dict, info: dict) -> np.ndarray | None:
        self._tick += 1
        if self._tick == 0 or self._tick % self.stride:
            return None
        self.chain.observe(np.array([obs["tail"][-1, :2], obs["neighbour"][-1, :2]]))
        if "team" in info:
            self.chain.share(info["team"][self.robots][::-1])
        t, head = self.chain.head
        return head.copy() if t > 0 else None

    def latest(self) -> tuple[int, np.ndarray]:
        """(the command tick it is for, the Head's position): the estimate to score."""
        step, head = self.chain.head
        return step * self.stride, head
