"""Tracking health: what the tracker reported, frame by frame, against the truth the simulator
knows, so that no run hands over wrong poses without saying so.

Per robot, over the frames the tracker processed (dropped frames are the imaging chain's
realistic noise and are counted apart): the share detected among the frames where it was in view
(an obstacle hiding its marker, by the truth, is the scene, not the tracker), the median / p95 /
p99 position error and the median heading error of its detections, and identity errors (a
detection nearer another robot's true pose than its own). Errors are the tracker's own: measured
before the scenario's marker jitter is added (that jitter is noise the user asked for, of known
sigma, recorded beside).

`TrackingHealth.judged(cfg)` judges the figures against a scenario's `[tracking]` limits; each
finding is one line naming the robot, the figure and its likely cause for the scenario's
markers.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from macrostate_mj.chain.markers import ColourMarkers
from macrostate_mj.chain.scenario import ScenarioConfig
from macrostate_mj.chain.scene import Obstacle
from macrostate_mj.chain.tags import ArucoMarkers
from macrostate_mj.chain.tracking import TrackingLimits
from macrostate_mj.chain.world import World
from macrostate_mj.core.angles import wrap_angle
from macrostate_mj.vision.occlusion import occluded

# Likely causes, by marker kind and by what the figures show, each naming a fix (docs:
# how-to/tracking-health).
EDGE = ("or its marker leaves the frame near the image's edge (markers stand above the floor a "
        "fitted camera frames: widen camera.fovy)")
CAUSES: dict[type, dict[str, str]] = {
    ColourMarkers: {
        "identity": ("its marker's colour is found on another robot (two markers the classifier "
                     "cannot tell apart, or a robot part rendered in marker colour): run "
                     "`macrostate-mj scenario check`, use fewer robots or [markers] kind = "
                     "\"aruco\""),
        "median_error": ("pixels of its marker's colour elsewhere in view pull the fit (a robot "
                         "part, the floor or an obstacle rendered in marker colour: run "
                         "`macrostate-mj scenario check` and recolour it grey), a lens the "
                         "calibration does not undo, or a limit tighter than the tracker's "
                         "accuracy (about 1 mm in the built-in labs)"),
        "detected": ("too few of its marker's pixels pass the colour rule (a marker small in "
                     "the image, blur, or light that shifts its hue: lower the camera or enlarge "
                     f"the marker), {EDGE}"),
    },
    ArucoMarkers: {
        "identity": ("a tag decoded as another robot's id (a dictionary too small for the "
                     "image's noise: use one with fewer ids, e.g. DICT_4X4_50)"),
        "median_error": ("its tag's corners are misplaced (a lens the calibration does not "
                         "undo, or tags too small in the image: lower the camera)"),
        "detected": ("its tag is not decoded (cells under about 3 px in the image, or blur: "
                     f"lower the camera or use a dictionary of fewer bits), {EDGE}"),
    },
}
NO_FRAMES = "every frame was dropped or the run ended before its first camera tick"


@dataclass(frozen=True)
class RobotHealth:
    """One robot's tracking figures over a run (errors in mm and degrees; NaN when it was
    never detected)."""

    robot: str
    frames: int                 # frames processed in which it was in view
    hidden: int                 # frames an obstacle hid its marker (not counted against it)
    detected: float             # share of `frames` in which it was detected (NaN: no frames)
    median_mm: float
    p95_mm: float
    p99_mm: float
    heading_deg: float          # median absolute heading error
    identity: float             # share of `frames` whose detection is nearer another's truth


@dataclass(frozen=True)
class Finding:
    """A figure past its limit: which robot, which figure, and why it likely is."""

    robot: str
    figure: str
    value: float
    limit: float
    cause: str

    def describe(self) -> str:
        if self.figure == "frames":
            return f"no frame tracked: {self.cause}; run longer or lower noise.drop_prob"
        if self.figure == "detected":
            what = f"detected in {self.value:.1%} of the frames (limit {self.limit:.0%})"
        elif self.figure == "median_error":
            what = (f"tracked {self.value * 1000:.1f} mm from the truth at the median (limit "
                    f"{self.limit * 1000:g} mm)")
        else:
            what = (f"identity errors in {self.value:.1%} of the frames (limit "
                    f"{self.limit:.0%})")
        return f"robot {self.robot} {what}: {self.cause}"


@dataclass(frozen=True)
class TrackingHealth:
    """A run's (or an episode's) tracking figures, per robot."""

    robots: tuple[RobotHealth, ...]

    def findings(self, limits: TrackingLimits, markers: object = ColourMarkers()
                 ) -> list[Finding]:
        """Every figure past `limits`, worst robots' first within each figure, each with the
        likely cause for the scenario's kind of `markers`. A run that tracked no frame at all
        is a finding too (nothing was checked)."""
        causes = CAUSES[type(markers)]
        if all(r.frames + r.hidden == 0 for r in self.robots):
            return [Finding("all", "frames", 0.0, 1.0, NO_FRAMES)]
        out = []
        for r in self.robots:
            if r.frames == 0:              # hidden in every frame: nothing to judge
                continue
            if r.identity > limits.max_identity_errors:
                out.append(Finding(r.robot, "identity", r.identity, limits.max_identity_errors,
                                   causes["identity"]))
            elif r.detected > 0 and r.median_mm / 1000 > limits.max_median_error:
                out.append(Finding(r.robot, "median_error", r.median_mm / 1000,
                                   limits.max_median_error, causes["median_error"]))
            if r.detected < limits.min_detected:
                out.append(Finding(r.robot, "detected", r.detected, limits.min_detected,
                                   causes["detected"]))
        order = {"identity": 0, "median_error": 1, "detected": 2}
        return sorted(out, key=lambda f: (order[f.figure], -abs(f.value - f.limit)))

    def judged(self, cfg: ScenarioConfig) -> list[Finding]:
        """The findings against scenario `cfg`'s `[tracking]` limits, in its markers' words."""
        return self.findings(cfg.tracking, cfg.markers)

    def summary(self, marker_jitter: float = 0.0) -> str:
        """One line: the worst robot's figures (robots never in view left out). They are the
        tracker's own; a scenario's `marker_jitter` (sigma, m) is added after them to the
        tracked columns a dataset holds, and the line says so."""
        seen = [r for r in self.robots if r.frames]
        if not seen:
            return "no frames tracked"
        worst = min(seen, key=lambda r: r.detected)
        errs = [r for r in seen if r.detected > 0]

        def top(key: str) -> str:
            values = [getattr(r, key) for r in errs]
            return f"{max(values):.1f}" if values else "n/a"

        line = (f"{len(seen)} robots, detected >= {worst.detected:.1%} ({worst.robot}), median "
                f"error <= {top('median_mm')} mm, p99 <= {top('p99_mm')} mm, heading <= "
                f"{top('heading_deg')} deg, identity errors <= "
                f"{max(r.identity for r in seen):.1%}")
        if marker_jitter > 0:     # what comparing a dataset with its truth columns shows
            line += (f" (the tracker's own error; the tracked columns add marker_jitter, sigma "
                     f"{1000 * marker_jitter:g} mm a coordinate)")
        return line


    def as_dict(self) -> dict:
        """For a manifest: per robot, its figures (NaN written as None)."""
        def clean(v: object) -> object:
            return None if isinstance(v, float) and math.isnan(v) else v

        return {r.robot: {k: clean(v) for k, v in asdict(r).items() if k != "robot"}
                for r in self.robots}

    @classmethod
    def from_dict(cls, data: dict, names: list[str] | None = None) -> TrackingHealth:
        """Back from `as_dict` (a cached episode's figures), robots in chain order `names`
        (JSON written with sorted keys loses it)."""
        return cls(tuple(RobotHealth(name, **{k: math.nan if v is None else v
                                              for k, v in data[name].items()})
                         for name in (names or list(data))))


def worst_of(reports: list[TrackingHealth]) -> TrackingHealth:
    """Per robot, the worst figure over several episodes' reports (frames summed): what a
    collection's one-line summary shows."""
    def pick(values: list[float], fn) -> float:
        finite = [v for v in values if not math.isnan(v)]
        return fn(finite) if finite else math.nan

    robots = []
    for rs in zip(*(r.robots for r in reports), strict=True):
        judged = [r for r in rs if r.frames]          # an episode where it was always hidden:
        robots.append(RobotHealth(                    # nothing to judge
            rs[0].robot, sum(r.frames for r in rs), sum(r.hidden for r in rs),
            pick([r.detected for r in judged], min),
            *(pick([getattr(r, k) for r in judged], max)
              for k in ("median_mm", "p95_mm", "p99_mm", "heading_deg")),
            pick([r.identity for r in judged], max)))
    return TrackingHealth(tuple(robots))


class HealthMonitor:
    """Accumulates, frame by frame, the tracker's detections against the truth; `report()`
    gives the figures. Cheap: a few numpy operations on (n, n) arrays per processed frame."""

    def __init__(self, names: list[str], marker_height: float = 0.0,
                 occluders: tuple[Obstacle, ...] = (), marker_area: float = 0.0):
        self.names = list(names)
        self.marker_height, self.occluders = marker_height, occluders
        self.marker_size = float(np.sqrt(marker_area))     # as the trackers' occlusion rule
        self.reset()

    @classmethod
    def for_world(cls, world: World) -> HealthMonitor:
        """The monitor of a chain world: its robots, marker plane and size, obstacles."""
        return cls(world.names, world.marker_height, world.scenario.obstacles, world.marker_area)

    def reset(self) -> None:
        self._in_view: list[np.ndarray] = []
        self._detected: list[np.ndarray] = []
        self._error: list[np.ndarray] = []
        self._heading: list[np.ndarray] = []
        self._identity: list[np.ndarray] = []

    def add(self, detected: np.ndarray, poses: np.ndarray, truth: np.ndarray,
            camera: np.ndarray | None = None) -> None:
        """One processed frame: the tracker's flags (n,) and poses (n, 3) (NaN where missed),
        the true poses then (n, 3), and the camera's position (for occlusion by obstacles)."""
        n = len(truth)
        in_view = np.ones(n, bool)
        if self.occluders and camera is not None:
            in_view = ~occluded(truth[:, :2], self.marker_height, camera, self.occluders,
                                self.marker_size)
        diff = poses[:, None, :2] - truth[None, :, :2]              # (n tracked, n truth, 2)
        dist = np.hypot(diff[..., 0], diff[..., 1])
        own = np.diagonal(dist).copy()
        np.fill_diagonal(dist, np.inf)
        seen = detected & in_view
        self._in_view.append(in_view)
        self._detected.append(seen)
        self._error.append(np.where(seen, own, np.nan))
        self._heading.append(np.where(seen, np.abs(wrap_angle(poses[:, 2] - truth[:, 2])),
                                      np.nan))
        self._identity.append(seen & (dist.min(axis=1, initial=np.inf) < own))

    def report(self) -> TrackingHealth:
        if not self._in_view:
            return TrackingHealth(tuple(RobotHealth(nm, 0, 0, *[math.nan] * 6)
                                        for nm in self.names))
        in_view = np.array(self._in_view)
        det = np.array(self._detected)
        err = np.array(self._error) * 1000
        head = np.degrees(np.array(self._heading))
        ident = np.array(self._identity)
        robots = []
        for i, name in enumerate(self.names):
            frames = int(in_view[:, i].sum())
            e = err[det[:, i], i]
            q = np.percentile(e, [50, 95, 99]) if len(e) else [math.nan] * 3
            robots.append(RobotHealth(
                name, frames, int(len(in_view) - frames),
                float(det[:, i].sum() / frames) if frames else math.nan,
                *(float(v) for v in q),
                float(np.median(head[det[:, i], i])) if len(e) else math.nan,
                float(ident[:, i].sum() / frames) if frames else math.nan))
        return TrackingHealth(tuple(robots))
