"""Rerun `.rrd` recordings of a run on a `sim_time` timeline (rerun 0.41).

What a recording holds, and the layout it opens on (its blueprint):
- `world/`: the arena, each robot's true pose, heading and trail, the Head's waypoint and, when
  the run was tracked, the tracker's poses beside the truth (2D, metres);
- `world3d/`: the robots' geometry from the compiled MJCF (boxes, spheres, cylinders, meshes)
  moving with their bodies, and the floor;
- `camera/overhead`: the camera frame at the pose rate;
- `metrics/`: time series of neighbour spacing (m), speed (m/s) and, tracked, the tracker's
  own error (mm, against the truth at the moment it saw the robot).

`log_chain_estimates` records offline ReTLo estimates instead (no simulation): the truth, the
estimates and, for a model with uncertainty, each estimate's 90 % ellipse; `log_ellipses` draws
such ellipses into any recording (a live run's `RerunRecorder.rec` too).
"""

from __future__ import annotations

import itertools
from pathlib import Path

import mujoco
import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from macrostate_mj.chain.sim import ChainSim
from macrostate_mj.core.io import AtomicFile
from macrostate_mj.vision.camera import OverheadRenderer
from viz.video import Recorder, Trails


def blueprint() -> rrb.Blueprint:
    """2D world and 3D robots on the left; camera and the time series on the right."""
    return rrb.Blueprint(rrb.Horizontal(
        rrb.Vertical(rrb.Spatial2DView(origin="world", name="chain (truth, tracked)"),
                     rrb.Spatial3DView(origin="world3d", name="robots (MJCF)")),
        rrb.Vertical(rrb.Spatial2DView(origin="camera", name="overhead camera"),
                     rrb.TimeSeriesView(origin="metrics/spacing_m", name="spacing (m)"),
                     rrb.TimeSeriesView(origin="metrics/speed_m_s", name="speed (m/s)"),
                     rrb.TimeSeriesView(origin="metrics/tracker_error_mm",
                                        name="tracker error (mm)")),
        column_shares=[3, 2]))


def _xyzw(wxyz: np.ndarray) -> np.ndarray:
    return np.asarray(wxyz)[..., [1, 2, 3, 0]]


def log_geometry(rec: rr.RecordingStream, model: mujoco.MjModel, bodies: list[int],
                 root: str = "world3d") -> None:
    """Static shapes of the visible geoms (groups 0-2) of `bodies`, each under its body's
    entity, so that logging the body's transform moves them."""
    for b in bodies:
        for g in np.flatnonzero(model.geom_bodyid == b):
            if model.geom_group[g] > 2:
                continue
            path = f"{root}/{model.body(b).name}/geom{g}"
            pos, quat = model.geom_pos[g], _xyzw(model.geom_quat[g])
            size, rgba = model.geom_size[g], (model.geom_rgba[g] * 255).astype(np.uint8)
            kind = model.geom_type[g]
            if kind == mujoco.mjtGeom.mjGEOM_BOX:
                shape = rr.Boxes3D(half_sizes=[size], centers=[pos], quaternions=[quat],
                                   colors=[rgba], fill_mode="solid")
            elif kind == mujoco.mjtGeom.mjGEOM_SPHERE:
                shape = rr.Ellipsoids3D(radii=[[size[0]] * 3], centers=[pos], colors=[rgba],
                                        fill_mode="solid")
            elif kind == mujoco.mjtGeom.mjGEOM_CYLINDER:
                shape = rr.Cylinders3D(lengths=[2 * size[1]], radii=[size[0]], centers=[pos],
                                       quaternions=[quat], colors=[rgba], fill_mode="solid")
            elif kind == mujoco.mjtGeom.mjGEOM_MESH:
                m = model.geom_dataid[g]
                v0, nv = model.mesh_vertadr[m], model.mesh_vertnum[m]
                f0, nf = model.mesh_faceadr[m], model.mesh_facenum[m]
                rot = np.empty(9)
                mujoco.mju_quat2Mat(rot, model.geom_quat[g])
                verts = model.mesh_vert[v0:v0 + nv] @ rot.reshape(3, 3).T + pos
                shape = rr.Mesh3D(vertex_positions=verts, triangle_indices=model.mesh_face[
                    f0:f0 + nf], albedo_factor=rgba)
            else:
                continue
            rec.log(path, shape, static=True)


class RerunRecorder(Recorder):
    """A periodic hook logging the chain at the pose rate (see the module docstring); with a
    `tracker` (anything with `latest`, `latest_truth` and `detected`), its output too."""

    def __init__(self, path: str | Path, sim: ChainSim, rate_hz: float, phase: float = 0.0,
                 image_every: int = 1, trail_seconds: float = 8.0,
                 tracker: object | None = None):
        self.path = Path(path)
        self.period, self.phase = 1 / rate_hz, phase                # a `Hook`
        self.rec = rr.RecordingStream("macrostate-mj")
        self._file = AtomicFile(self.path)
        self.rec.save(str(self._file.tmp), default_blueprint=blueprint())
        self.renderer = OverheadRenderer(sim.model)
        self.image_every = image_every
        self.tracker = tracker
        self.trails = Trails(sim.n, max(2, int(trail_seconds * rate_hz)))
        self.calls = 0
        self.names = sim.world.names
        self.colours = (sim.world.colours * 255).astype(np.uint8)
        self._last: tuple[float, np.ndarray] | None = None
        model = sim.model
        self.bodies = [b for b in range(1, model.nbody)
                       if np.any((model.geom_bodyid == b) & (model.geom_group <= 2))]
        hx, hy = np.array(sim.cfg.arena) / 2
        self.rec.log("world/arena", rr.LineStrips2D([[[-hx, -hy], [hx, -hy], [hx, hy],
                                                      [-hx, hy], [-hx, -hy]]]), static=True)
        self.rec.log("world3d/floor", rr.Boxes3D(half_sizes=[[hx, hy, 0.001]],
                                                 centers=[[0, 0, -0.001]],
                                                 colors=[[200, 200, 195]], fill_mode="solid"),
                     static=True)
        log_geometry(self.rec, model, self.bodies)

    def capture(self, sim: ChainSim) -> None:
        rec = self.rec
        rec.set_time("sim_time", duration=sim.time)
        poses = sim.poses
        self.trails.add(poses[:, :2])
        radius = sim.world.footprint_radius
        heading = 1.5 * radius * np.column_stack([np.cos(poses[:, 2]), np.sin(poses[:, 2])])
        rec.log("world/robots", rr.Points2D(poses[:, :2], radii=radius, colors=self.colours,
                                            labels=self.names))
        rec.log("world/headings", rr.Arrows2D(vectors=heading, origins=poses[:, :2],
                                              colors=self.colours))
        rec.log("world/trails", rr.LineStrips2D([np.array(t) for t in self.trails.points],
                                                colors=self.colours))
        if sim.planner.target is not None:
            rec.log("world/waypoint", rr.Points2D([sim.planner.target], radii=radius / 2,
                                                  colors=[[220, 0, 0]]))
        for b in self.bodies:
            rec.log(f"world3d/{sim.model.body(b).name}",
                    rr.Transform3D(translation=sim.data.xpos[b],
                                   quaternion=_xyzw(sim.data.xquat[b])))
        if self.calls % self.image_every == 0:
            rec.log("camera/overhead", rr.Image(self.renderer.render(sim.data)).compress(80))
        self._log_metrics(sim, poses)
        self.calls += 1

    def log_points(self, name: str, xy: np.ndarray, radius: float, colour: tuple[int, ...],
                   label: str | None = None, static: bool = False) -> None:
        """Extra points in the 2-D world view (an estimate, a virtual object's centre)."""
        xy = np.atleast_2d(xy)
        self.rec.log(f"world/{name}", rr.Points2D(xy, radii=radius, colors=[colour],
                                                  labels=None if label is None else [label]),
                     static=static)

    def log_ellipse(self, name: str, mean: np.ndarray, cov: np.ndarray,
                    colour: tuple[int, ...]) -> None:
        """An estimate's 90 % ellipse (mean (2,), cov (2, 2), metres) in the 2-D world view,
        beside its `log_points`."""
        log_ellipses(self.rec, f"world/{name}", np.atleast_2d(mean), np.asarray(cov)[None],
                     np.array([colour], np.uint8))

    def _log_metrics(self, sim: ChainSim, poses: np.ndarray) -> None:
        rec = self.rec
        gaps = np.linalg.norm(np.diff(poses[:, :2], axis=0), axis=1)
        for (a, b), gap in zip(itertools.pairwise(self.names), gaps, strict=True):
            rec.log(f"metrics/spacing_m/{a}-{b}", rr.Scalars(gap))
        if self._last is not None and sim.time > self._last[0]:
            speed = np.linalg.norm(poses[:, :2] - self._last[1][:, :2], axis=1) / (
                sim.time - self._last[0])
            for name, v in zip(self.names, speed, strict=True):
                rec.log(f"metrics/speed_m_s/{name}", rr.Scalars(v))
        self._last = (sim.time, poses.copy())
        if self.tracker is None:
            return
        seen = self.tracker.detected
        latest, truth = self.tracker.latest, self.tracker.latest_truth
        rec.log("world/tracked", rr.Points2D(latest[seen, :2], radii=sim.world.footprint_radius
                                             / 3, colors=[[255, 255, 255]],
                                             labels=[f"{n} (tracked)" for n, s in
                                                     zip(self.names, seen, strict=True) if s]))
        err_mm = 1000 * np.linalg.norm(latest[:, :2] - truth[:, :2], axis=1)
        for name, s, e in zip(self.names, seen, err_mm, strict=True):
            if s:
                rec.log(f"metrics/tracker_error_mm/{name}", rr.Scalars(e))

    def finish(self) -> None:
        self.rec.flush()
        self.rec.disconnect()
        self.renderer.close()
        self._file.commit()

    def abort(self) -> None:
        self.rec.disconnect()
        self.renderer.close()
        self._file.discard()


def log_ellipses(rec: rr.RecordingStream, entity: str, mean: np.ndarray, cov: np.ndarray,
                 colours: np.ndarray, p: float = 0.9) -> None:
    """The p-regions of Gaussians N(mean (k, 2), cov (k, 2, 2)) (metres) as closed outlines,
    the non-finite ones left out."""
    from estimators.retlo.gaussian import ellipse

    ok = np.isfinite(mean).all(-1) & np.isfinite(cov).all((-1, -2))
    strips = [np.vstack([e, e[:1]]) for e in (ellipse(m, c, p) for m, c in
                                              zip(mean[ok], cov[ok], strict=True))]
    rec.log(entity, rr.LineStrips2D(strips, colors=colours[ok]))


def log_chain_estimates(path: str | Path, world: np.ndarray, est: np.ndarray,
                        cov: np.ndarray | None, step_s: float = 0.5) -> Path:
    """An `.rrd` of offline ReTLo estimates: chains (B, S, N, 3) and estimates in metres, file
    order (NaN: not estimated), one instance after another on a `sim_time` timeline at the
    2 Hz log rate; with `cov` (B, S, N, 2, 2) the estimates' 90 % ellipses."""
    n_inst, n_steps, n_robots = world.shape[:3]
    colours = np.array([[230, 60, 180], *([[40, 150, 255]] * (n_robots - 2)), [255, 220, 0]],
                       np.uint8)
    from macrostate_mj.formats.thymioloc import robot_names

    names = robot_names(n_robots)
    rec = rr.RecordingStream("macrostate-mj")
    out = AtomicFile(Path(path))
    rec.save(str(out.tmp))
    try:
        for i in range(n_inst):
            for t in range(n_steps):
                rec.set_time("sim_time", duration=(i * n_steps + t) * step_s)
                rec.log("world/truth", rr.Points2D(world[i, t, :, :2], radii=0.02,
                                                   colors=colours, labels=names))
                seen = np.isfinite(est[i, t, :, :2]).all(-1)
                rec.log("world/estimates", rr.Points2D(est[i, t, seen, :2], radii=0.012,
                                                       colors=colours[seen],
                                                       labels=[f"{n} (est)" for n, s in
                                                               zip(names, seen, strict=True)
                                                               if s]))
                if cov is not None:
                    log_ellipses(rec, "world/ellipses_90", est[i, t, :, :2], cov[i, t],
                                 colours)
        rec.flush()
        rec.disconnect()
    except BaseException:
        rec.disconnect()
        out.discard()
        raise
    out.commit()
    return Path(path)
