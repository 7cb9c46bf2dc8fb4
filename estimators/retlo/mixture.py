"""A deep ensemble (Lakshminarayanan et al., 2017) of Gaussian ReTLo modules trained with
different seeds, run as one chain `Module`.

Each member sees the same window and gives its own Gaussian; the ensemble's estimate is their
equal-weight mixture moment-matched to one Gaussian (`gaussian.moment_match`: the mean of the
means, the mean covariance plus the spread of the means), so the chain, its Monte Carlo
(`propagate`), calibration and ellipses treat it as any one uncertain module. Headings are the
members' circular means. Members must read the same window (history and frame); their own
feature layouts (angles, flags) may differ.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from estimators.retlo.chain import Features, Module
from estimators.retlo.frames import FrameEstimate, Window
from estimators.retlo.gaussian import GAUSSIAN_REGIONS, circular_mean, moment_match
from macrostate_mj.core.errors import UserError


class GaussianEnsemble:
    """Members' Gaussians, mixed and moment-matched (see the module docstring)."""

    uncertain = True
    regions = GAUSSIAN_REGIONS   # members' radii fit their own Gaussians, not the mixture's

    def __init__(self, members: Sequence[Module]) -> None:
        if len(members) < 2:
            raise UserError("an ensemble needs at least two models; pass --model more than once")
        if not all(getattr(m, "uncertain", False) for m in members):
            raise UserError("every ensemble member must have uncertainty; train each with "
                            "`train retlo --uncertainty gaussian`")
        if len({(m.history, m.rotate) for m in members}) != 1:
            raise UserError("ensemble members must share history and frame; train them with "
                            "the same --history and frame flags")
        self.members = list(members)
        self.history, self.rotate = members[0].history, members[0].rotate
        self._sizes: list[int] = []

    def features(self, win: Window) -> Features:
        """Every member's own features, one after another (their sizes kept for `estimate`)."""
        parts = [m.features(win) for m in self.members]
        self._sizes = [len(p) for p in parts]
        return tuple(a for p in parts for a in p)

    def estimate(self, x: Features) -> FrameEstimate:
        ests, at = [], 0
        for member, size in zip(self.members, self._sizes, strict=True):
            ests.append(member.estimate(x[at:at + size]))
            at += size
        mean, cov = moment_match(np.stack([e.head_xy for e in ests]),
                                 np.stack([e.head_cov for e in ests]))

        def angle(attr: str) -> np.ndarray | None:
            vals = [getattr(e, attr) for e in ests]
            return None if any(v is None for v in vals) else circular_mean(np.stack(vals))

        return FrameEstimate(mean, angle("head_theta"), angle("fol_theta"),
                             angle("fol_theta_next"), cov)
