"""Chapter 3's Rand-Only phase (§3.3): the Tail adds w ~ N(0, σ² I) to its destination, σ =
0.75 × 11 cm, alternating random and passive modes every 6 log steps; and the SR phase's Tail
on a stand-in novelty model."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from macrostate_mj.chain.motion import ROBOT_SIZE_M
from macrostate_mj.chain.scenarios import get_scenario
from macrostate_mj.chain.sim import ChainSim, Every
from macrostate_mj.chain.world import build_world
from macrostate_mj.core.errors import UserError
from macrostate_mj.tails.collection import PolicyConfig
from macrostate_mj.tails.srs import SRSConfig


class _Recorder:
    """Stands in for the simulation: the policy only writes `tail_offset` (at a time)."""

    tail_offset = np.zeros(2)
    time = 0.0


def _offsets(cfg: PolicyConfig, seed: int, steps: int) -> np.ndarray:
    policy, sim, out = cfg.build(np.random.default_rng(seed)), _Recorder(), []
    for _ in range(steps):
        policy(sim)
        out.append(sim.tail_offset.copy())
    return np.array(out)


def test_draws_are_seeded_and_alternate_every_six_steps():
    cfg = PolicyConfig("random")
    a, b = _offsets(cfg, 3, 600), _offsets(cfg, 3, 600)
    assert np.array_equal(a, b) and not np.array_equal(a, _offsets(cfg, 4, 600))
    modes = np.linalg.norm(a, axis=1).reshape(-1, 6) > 0      # blocks of 6 steps
    assert modes[0::2].all() and not modes[1::2].any()        # random, passive, random, ...
    random_part = a.reshape(-1, 6, 2)[0::2].reshape(-1, 2)
    sigma = cfg.sigma * ROBOT_SIZE_M
    assert np.std(random_part, axis=0) == pytest.approx([sigma, sigma], rel=0.15)
    assert abs(np.mean(random_part)) < 0.15 * sigma
    assert not np.any(_offsets(PolicyConfig("passive"), 3, 60))


def test_the_tail_drives_to_the_perturbed_destination():
    """With a constant offset w, the Tail sits w away from where its rule would put it: the
    mean residual p_T - D (D at distance d from its neighbour, on the line to the Tail) moves
    by w against the passive run, over several seeds."""
    offset = np.array([0.05, -0.06])
    cfg = get_scenario("lab")

    def mean_residual(seed: int, w: np.ndarray) -> np.ndarray:
        sim = ChainSim(build_world(cfg, 3))
        sim.reset(np.random.default_rng(seed))
        res = []

        def hold(s: ChainSim) -> None:
            s.tail_offset = w
            tail, ahead = s.poses[-1, :2], s.poses[-2, :2]
            u = (tail - ahead) / np.linalg.norm(tail - ahead)
            res.append(tail - (ahead + cfg.spacing * u))

        sim.run(60.0, [Every(0.5, hold)])
        return np.mean(res[40:], axis=0)           # after the Tail has settled

    for seed in (21, 22, 23):
        shift = mean_residual(seed, offset) - mean_residual(seed, np.zeros(2))
        assert np.linalg.norm(shift - offset) < 0.03, (seed, shift)


def test_bad_policy_input():
    with pytest.raises(UserError, match="unknown policy"):
        PolicyConfig("wild")
    with pytest.raises(UserError, match="--sigma"):
        PolicyConfig("random", -1.0)


@dataclass(frozen=True)
class _Leftmost:
    """A stand-in novelty model (no torch, no estimators): ζ says nothing moves, and e is how
    far left of the Tail→F axis H ends, so the Tail's pick is known."""

    def load(self) -> _Leftmost:
        return self

    def predict_next(self, windows: np.ndarray) -> np.ndarray:
        return windows[:, -1]

    def novelty(self, windows: np.ndarray) -> np.ndarray:
        return windows[:, -1, 5]


def test_the_srs_tail_drives_to_its_pick_through_the_scorer_interface():
    """The SR phase's Tail needs only a `NoveltyScorer`: with SRS-Max, each scored step's pick
    is the candidate of largest e, and its offset is the one set."""
    sim = ChainSim(build_world(get_scenario("webots"), 3))
    sim.reset(np.random.default_rng(5))
    policy = SRSConfig(_Leftmost(), "max", k=6).build(np.random.default_rng([5, 2]))
    offsets = []
    sim.run(15.0, [Every(0.5, lambda s: (policy(s), offsets.append(s.tail_offset.copy())))])
    rec = policy.records()
    es, picks = np.array(rec["e"].to_pylist()), rec["pick"].to_numpy()
    assert rec.num_rows >= 6 and np.array_equal(picks, np.argmax(es, axis=1))
    cands = np.array(rec["offsets"].to_pylist()).reshape(rec.num_rows, 6, 2)
    times = np.round(rec["t"].to_numpy() / 0.5).astype(int)
    assert np.array_equal(np.array(offsets)[times], cands[np.arange(rec.num_rows), picks])
