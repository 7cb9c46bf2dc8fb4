"""The caging episode's recordings: a video with the object, its boundary and the Tail's estimate
of the Head drawn in (none of which the scene shows), and a rerun recording with the object and
the estimate as points.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np

from macrostate_mj.chain.caging_mission import CagingConfig
from macrostate_mj.chain.sim import ChainSim
from viz.rerun_log import RerunRecorder
from viz.video import Recorder, VideoRecorder

Estimate = Callable[[], np.ndarray | None]       # the Tail's latest estimate of the Head, if any
ESTIMATE_COLOUR = (60, 60, 230)                  # BGR; the rerun view gets the RGB twin below


def caging_recorders(sim: ChainSim, caging: CagingConfig, video: Path | None,
                     rerun: Path | None, estimate: Estimate) -> list[tuple[int, Recorder]]:
    """(every how many command ticks, recorder): a 10 fps video and a 10 Hz rerun recording,
    each where a path is given."""
    out: list[tuple[int, Recorder]] = []
    every = max(1, int(round(sim.cfg.command_hz / 10)))
    if video is not None:
        out.append((every, VideoRecorder(video, sim, fps=10.0,
                                         decorate=_decorate(caging, estimate))))
    if rerun is not None:
        out.append((every, CagingRerun(rerun, sim, caging, estimate)))
    return out


def _decorate(caging: CagingConfig, estimate: Estimate
              ) -> Callable[[np.ndarray, Callable[[np.ndarray], np.ndarray]], None]:
    """`VideoRecorder`'s decorate: the object (filled), the boundary (a ring) and the estimate
    (a labelled circle)."""

    def decorate(bgr: np.ndarray, px: Callable[[np.ndarray], np.ndarray]) -> None:
        c = px(np.array(caging.centre))[0]
        scale = np.linalg.norm(px(np.array(caging.centre) + [1.0, 0.0])[0] - c)
        centre = tuple(int(v) for v in np.round(c))
        cv2.circle(bgr, centre, int(caging.object_radius * scale), (150, 150, 150), -1)
        cv2.circle(bgr, centre, int(caging.ring_radius * scale), (60, 60, 60), 1, cv2.LINE_AA)
        head = estimate()
        if head is not None:
            u, v = np.round(px(head)[0]).astype(int)
            cv2.circle(bgr, (int(u), int(v)), 9, ESTIMATE_COLOUR, 2, cv2.LINE_AA)
            cv2.putText(bgr, "Tail's estimate of H", (int(u) + 11, int(v) - 6),
                        cv2.FONT_HERSHEY_SIMPLEX, 0.4, ESTIMATE_COLOUR, 1, cv2.LINE_AA)
    return decorate


class CagingRerun(RerunRecorder):
    """A 10 Hz rerun recording with the object (static) and, at each capture, the Tail's
    estimate of the Head."""

    def __init__(self, path: Path, sim: ChainSim, caging: CagingConfig, estimate: Estimate):
        super().__init__(path, sim, rate_hz=10.0)
        self.estimate = estimate
        self.log_points("object", np.array(caging.centre), caging.object_radius,
                        (150, 150, 150), "object", static=True)

    def capture(self, sim: ChainSim) -> None:
        super().capture(sim)
        head = self.estimate()
        if head is not None:
            self.log_points("head_estimate", head, 0.012, (230, 60, 60), "Tail's estimate of H")
