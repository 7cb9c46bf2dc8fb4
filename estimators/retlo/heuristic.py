"""The 2X heuristic of §2.6.2.3 (robot k+2 ≈ robot k + 2 (robot k+1 − robot k)): a reference
for how much the learned modules add, in both chapters."""

from __future__ import annotations

import numpy as np

from estimators.retlo.chain import Features
from estimators.retlo.frames import FrameEstimate, Window, extrapolate_2x
from macrostate_mj.core.frames import to_frame


class Heuristic2X:
    """As a chain `Module`: the Head at twice the Follower in the frame; headings along the
    chain, i.e. 0 in the frame."""

    history = 10  # uses no history, but starts predicting where the learned models do
    rotate = True

    def features(self, win: Window) -> Features:
        return (to_frame(win.fol[:, win.history, :2], win.origin, win.alpha),)

    def estimate(self, x: Features) -> FrameEstimate:
        zeros = np.zeros(len(x[0]))
        return FrameEstimate(extrapolate_2x(0.0, x[0]), head_theta=zeros, fol_theta=zeros)


def estimate_heuristic(sensed: np.ndarray, synced: np.ndarray, sync: np.ndarray) -> np.ndarray:
    """The heuristic in the world frame with chapter 2's knowledge (`chain.tracks_from_view`),
    memoryless between syncs: estimated positions (S, N, 2), Tail first."""
    steps, n = len(sensed), synced.shape[1]
    pos = np.full((steps, n, 2), np.nan)
    pos[:, :2] = sensed
    for k in range(n - 2):
        pos[:, k + 2] = extrapolate_2x(pos[:, k], pos[:, k + 1])
        pos[sync, k + 2] = synced[:, k + 2, :2]
    return pos
