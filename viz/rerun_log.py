"""Rerun `.rrd` recordings of a run: arena, poses, trails, waypoint and camera frames on a
`sim_time` timeline (rerun 0.41: `set_time(..., duration=s)`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import rerun as rr

from macrostate_mj.chain.sim import ChainSim
from macrostate_mj.core.io import AtomicFile
from macrostate_mj.vision.camera import OverheadRenderer
from viz.video import Recorder, Trails


class RerunRecorder(Recorder):
    """A periodic hook logging the chain; camera frames (JPEG) every `image_every` calls."""

    def __init__(self, path: str | Path, sim: ChainSim, rate_hz: float, phase: float = 0.0,
                 image_every: int = 4, trail_seconds: float = 8.0):
        self.path = Path(path)
        self.period, self.phase = 1 / rate_hz, phase                # a `Hook`
        self.rec = rr.RecordingStream("macrostate-mj")
        self._file = AtomicFile(self.path)
        self.rec.save(str(self._file.tmp))
        self.renderer = OverheadRenderer(sim.model)
        self.image_every = image_every
        self.trails = Trails(sim.n, max(2, int(trail_seconds * rate_hz)))
        self.calls = 0
        self.colours = (sim.world.colours * 255).astype(np.uint8)
        hx, hy = np.array(sim.cfg.arena) / 2
        self.rec.log("world/arena", rr.LineStrips2D([[[-hx, -hy], [hx, -hy], [hx, hy],
                                                      [-hx, hy], [-hx, -hy]]]), static=True)

    def capture(self, sim: ChainSim) -> None:
        rec = self.rec
        rec.set_time("sim_time", duration=sim.time)
        poses = sim.poses
        self.trails.add(poses[:, :2])
        heading = 0.08 * np.column_stack([np.cos(poses[:, 2]), np.sin(poses[:, 2])])
        rec.log("world/robots", rr.Points2D(poses[:, :2], radii=0.04, colors=self.colours,
                                            labels=sim.world.names))
        rec.log("world/headings", rr.Arrows2D(vectors=heading, origins=poses[:, :2],
                                              colors=self.colours))
        rec.log("world/trails", rr.LineStrips2D([np.array(t) for t in self.trails.points],
                                                colors=self.colours))
        if sim.planner.target is not None:
            rec.log("world/waypoint", rr.Points2D([sim.planner.target], radii=0.03,
                                                  colors=[[220, 0, 0]]))
        if self.calls % self.image_every == 0:
            rec.log("camera/overhead", rr.Image(self.renderer.render(sim.data)).compress(80))
        self.calls += 1

    def finish(self) -> None:
        self.rec.flush()
        self.rec.disconnect()
        self.renderer.close()
        self._file.commit()

    def abort(self) -> None:
        self.rec.disconnect()
        self.renderer.close()
        self._file.discard()
