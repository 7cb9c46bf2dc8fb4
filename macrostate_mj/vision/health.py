"""Tracking health: what the tracker reported, frame by frame, against the truth the simulator
knows, so that no run hands over wrong poses without saying so.

A pose is position, heading and identity, on the rows a user gets. Per robot: the share of the
dataset's rows in which it was detected, among those where it was in view (an obstacle
between its marker and the camera, by the truth and the camera's rays, is the scene, not the
tracker: those rows are counted as hidden, and a robot hidden too often is a finding of its
own); the same share over the frames the tracker processed, named as such; over its detections,
the median / p95 / p99 position error, the median and p99 heading error and the shares of
headings off by more than 30 and 90 degrees, and identity errors (a detection nearer another
robot's true pose than its own). Errors are the tracker's own: measured before the scenario's
marker jitter is added (that jitter is noise the user asked for, of known sigma, recorded
beside).

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
from macrostate_mj.chain.sim import PoseLog
from macrostate_mj.chain.tags import ArucoMarkers
from macrostate_mj.chain.tracking import TrackingLimits
from macrostate_mj.chain.world import World
from macrostate_mj.core.angles import wrap_angle
from macrostate_mj.vision.occlusion import occluded, scene_occluders

# Likely causes, by marker kind and by what the figures show, each naming a fix (docs:
# how-to/tracking-health).
EDGE = ("or its marker leaves the frame near the image's edge (markers stand above the floor a "
        "fitted camera frames: widen camera.fovy)")
HIDDEN = ("an obstacle stands between its marker and the camera (a robot parked or driving "
          "beside something taller than its marker, off the camera's axis): move or lower the "
          "obstacle, raise the camera over it, or raise [tracking] max_hidden if you mean it")
COLOUR_OFF = ("pixels of its marker's colour nearby pull the fit (another robot's marker "
              "touching it, or noise: lower the camera or enlarge the markers), a camera or "
              "lens the calibration does not undo ([noise] cam_tilt_deg, calibration error), "
              "or a limit tighter than the tracker's accuracy (about 1-2 mm in the built-in "
              "labs)")
COLOUR_HEADING = ("its triangle's apex is not resolved (a marker only a few pixels long in the "
                  "image, blur, or pixels of its colour nearby: lower the camera, enlarge the "
                  "marker, or use [markers] kind = \"aruco\")")
TAG_OFF = ("its tag's corners are misplaced (a lens the calibration does not undo, or tags too "
           "small in the image: lower the camera)")
TAG_HEADING = ("its tag's corners are found in the wrong order (tags too small or blurred in "
               "the image: lower the camera or use a dictionary of fewer bits)")
CAUSES: dict[type, dict[str, str]] = {
    ColourMarkers: {
        "identity": ("its marker's colour is found on another robot (two markers the classifier "
                     "cannot tell apart, or a robot part rendered in marker colour): run "
                     "`macrostate-mj scenario check`, use fewer robots or [markers] kind = "
                     "\"aruco\""),
        "median_error": COLOUR_OFF, "p99_error": COLOUR_OFF,
        "heading_flips": COLOUR_HEADING, "heading_off30": COLOUR_HEADING,
        "detected": ("too few of its marker's pixels pass the colour rule (a marker small in "
                     "the image, blur, or light that shifts its hue: lower the camera or enlarge "
                     f"the marker), {EDGE}"),
    },
    ArucoMarkers: {
        "identity": ("a tag decoded as another robot's id (a dictionary too small for the "
                     "image's noise: use one with fewer ids, e.g. DICT_4X4_50)"),
        "median_error": TAG_OFF, "p99_error": TAG_OFF,
        "heading_flips": TAG_HEADING, "heading_off30": TAG_HEADING,
        "detected": ("its tag is not decoded (cells under about 3 px in the image, or blur: "
                     f"lower the camera or use a dictionary of fewer bits), {EDGE}"),
    },
}
NO_FRAMES = "every frame was dropped or the run ended before its first camera tick"


@dataclass(frozen=True)
class RobotHealth:
    """One robot's tracking figures over a run (errors in mm and degrees; NaN when it was
    never detected, or, for the rows' figures, when no dataset rows were judged).

    Two detected shares, named apart: `detected` over the dataset's rows (what a user of
    `poses.parquet` gets: a row whose latest frame missed the robot, dropped frames included,
    is a miss), `detected_frames` over the frames the tracker processed. Position, heading and
    identity figures are over its detections (every row's tracked pose is one of them)."""

    robot: str
    frames: int                 # frames processed in which it was in view
    hidden: int                 # frames an obstacle hid its marker (not held against it)
    detected_frames: float      # share of `frames` in which it was detected (NaN: no frames)
    rows: int                   # dataset rows judged in which it was in view
    rows_hidden: int            # dataset rows in which it was hidden
    detected: float             # share of `rows` whose `detected` flag is set (NaN: no rows)
    median_mm: float
    p95_mm: float
    p99_mm: float
    heading_deg: float          # median absolute heading error
    heading_p99_deg: float      # its 99th percentile
    heading_off30: float        # share of detections whose heading errs by more than 30 deg
    heading_flips: float        # ... by more than 90 deg: a flipped heading
    identity: float             # share of detections nearer another robot's truth

    @property
    def hidden_share(self) -> tuple[float, str]:
        """Share of the dataset's rows (else of the frames) in which it was hidden, and which."""
        if self.rows + self.rows_hidden:
            return self.rows_hidden / (self.rows + self.rows_hidden), "rows"
        seen = self.frames + self.hidden
        return (self.hidden / seen if seen else math.nan), "frames"

    @property
    def detected_share(self) -> tuple[float, str]:
        """The share a run is judged on and what it is of: the rows', else the frames'."""
        return (self.detected, "rows") if self.rows else (self.detected_frames, "frames")


FIGURES = ("identity", "median_error", "p99_error", "heading_flips", "heading_off30",
           "detected", "hidden")      # findings in this order, worst robots first within each
# A figure left unsaid when one of these already is, for the same robot: another robot's pose
# (identity) makes its distances meaningless, a bad median implies a bad p99, a flip is 30 off.
SAYS_MORE = {"median_error": {"identity"}, "p99_error": {"identity", "median_error"},
             "heading_off30": {"heading_flips"}}


@dataclass(frozen=True)
class Finding:
    """A figure past its limit: which robot, which figure, and why it likely is."""

    robot: str
    figure: str
    value: float
    limit: float
    cause: str
    of: str = "frames"           # what a share is of: the dataset's rows or the frames

    def describe(self) -> str:
        if self.figure == "frames":
            return f"no frame tracked: {self.cause}; run longer or lower noise.drop_prob"
        v, lim = self.value, self.limit
        what = {
            "detected": f"detected in {v:.1%} of the {self.of} where it is in view (limit "
                        f"{lim:.0%})",
            "hidden": f"hidden by an obstacle in {v:.1%} of the {self.of} (limit "
                      f"{lim:.0%})",
            "median_error": f"tracked {v:.1f} mm from the truth at the median (limit {lim:g} mm)",
            "p99_error": f"tracked {v:.1f} mm from the truth at the 99th percentile (limit "
                         f"{lim:g} mm)",
            "heading_flips": f"headed more than 90 deg off (flipped) in {v:.1%} of its "
                             f"detections (limit {lim:.0%})",
            "heading_off30": f"headed more than 30 deg off in {v:.1%} of its detections "
                             f"(limit {lim:.0%})",
            "identity": f"identity errors in {v:.1%} of its detections (limit {lim:.0%})",
        }[self.figure]
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
            share, of = r.detected_share
            hidden, hidden_of = r.hidden_share
            if hidden > limits.max_hidden:
                out.append(Finding(r.robot, "hidden", hidden, limits.max_hidden, HIDDEN,
                                   hidden_of))
            if r.frames == 0:              # hidden in every frame: nothing more to judge
                continue
            past = [("identity", r.identity, limits.max_identity_errors),
                    ("median_error", r.median_mm, limits.max_median_mm),
                    ("p99_error", r.p99_mm, limits.max_p99_mm),
                    ("heading_flips", r.heading_flips, limits.max_heading_flips),
                    ("heading_off30", r.heading_off30, limits.max_heading_off30)]
            found: set[str] = set()
            for figure, value, limit in past:     # NaN (never detected): judged by `detected`
                if value > limit and not found & SAYS_MORE.get(figure, set()):
                    found.add(figure)
                    out.append(Finding(r.robot, figure, value, limit, causes[figure]))
            if share < limits.min_detected:
                out.append(Finding(r.robot, "detected", share, limits.min_detected,
                                   causes["detected"], of))
        order = {f: i for i, f in enumerate(FIGURES)}
        return sorted(out, key=lambda f: (order[f.figure], -abs(f.value - f.limit)))

    def judged(self, cfg: ScenarioConfig) -> list[Finding]:
        """The findings against scenario `cfg`'s `[tracking]` limits, in its markers' words."""
        return self.findings(cfg.tracking, cfg.markers)

    def described(self, cfg: ScenarioConfig) -> str:
        """`summary` with scenario `cfg`'s noise added to the dataset named beside it."""
        return self.summary(cfg.marker_jitter, cfg.marker_offset)

    def summary(self, marker_jitter: float = 0.0, marker_offset: float = 0.0) -> str:
        """One line: the worst robot's figures (robots never in view left out). They are the
        tracker's own; a scenario's `marker_jitter` (sigma, m, per frame) and `marker_offset`
        (sigma, m, per robot and episode) are added after them to the tracked columns a
        dataset holds, and the line says so: noise the user asked for, not judged."""
        seen = [r for r in self.robots if r.frames]
        if not seen:
            return "no frames tracked"
        worst = min(seen, key=lambda r: r.detected_share[0])
        share, of = worst.detected_share
        hid = max(self.robots, key=lambda r: np.nan_to_num(r.hidden_share[0]))
        errs = [r for r in seen if r.detected_frames > 0]

        def top(key: str, fmt: str = ".1f") -> str:
            values = [getattr(r, key) for r in errs]
            return format(max(values), fmt) if values else "n/a"

        frames = (f"; {worst.detected_frames:.1%} of its frames" if of == "rows" else "")
        line = (f"{len(seen)} robots, detected >= {share:.1%} of the {of} ({worst.robot}"
                f"{frames}), hidden <= {np.nan_to_num(hid.hidden_share[0]):.1%} ({hid.robot}), "
                f"median error <= {top('median_mm')} mm, p99 <= {top('p99_mm')} mm, heading "
                f"p99 <= {top('heading_p99_deg')} deg, off 30 deg <= "
                f"{top('heading_off30', '.1%')}, flipped <= {top('heading_flips', '.1%')}, "
                f"identity errors <= {max(r.identity for r in seen):.1%}")
        added = ([f"marker_jitter, sigma {1000 * marker_jitter:g} mm a coordinate"]
                 if marker_jitter > 0 else [])
        if marker_offset > 0:
            added.append(f"each robot's marker_offset, sigma {1000 * marker_offset:g} mm a "
                         "coordinate, fixed for an episode")
        if added:                 # what comparing a dataset with its truth columns shows
            line += (f" (the tracker's own error; the tracked columns add "
                     f"{' and '.join(added)})")
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
    """Per robot, the worst figure over several episodes' reports (counts summed): what a
    collection's one-line summary shows."""
    def pick(values: list[float], fn) -> float:
        finite = [v for v in values if not math.isnan(v)]
        return fn(finite) if finite else math.nan

    robots = []
    for rs in zip(*(r.robots for r in reports), strict=True):
        judged = [r for r in rs if r.frames]          # an episode where it was always hidden:
        rows = [r for r in rs if r.rows]              # nothing to judge
        robots.append(RobotHealth(
            rs[0].robot, *(sum(getattr(r, k) for r in rs) for k in ("frames", "hidden")),
            pick([r.detected_frames for r in judged], min),
            *(sum(getattr(r, k) for r in rs) for k in ("rows", "rows_hidden")),
            pick([r.detected for r in rows], min),
            *(pick([getattr(r, k) for r in judged], max)
              for k in ("median_mm", "p95_mm", "p99_mm", "heading_deg", "heading_p99_deg",
                        "heading_off30", "heading_flips", "identity"))))
    return TrackingHealth(tuple(robots))


class HealthMonitor:
    """Accumulates, frame by frame, the tracker's detections against the truth; `report()`
    gives the figures, and `report(log)` adds those of the dataset's rows. Cheap: a few numpy
    operations on (n, n) arrays per processed frame."""

    def __init__(self, names: list[str], marker_height: float = 0.0,
                 occluders: tuple[Obstacle, ...] = (), outline: np.ndarray | None = None):
        self.names = list(names)
        self.marker_height, self.occluders = marker_height, occluders
        # as the trackers' occlusion rule: the marker's outline (body frame) must show
        self.outline = np.zeros((1, 2)) if outline is None else np.asarray(outline, float)
        self.camera: np.ndarray | None = None              # where the last frame's camera was
        self.reset()

    @classmethod
    def for_world(cls, world: World) -> HealthMonitor:
        """The monitor of a chain world: its robots, marker plane and size, what can hide a
        marker (its obstacles)."""
        return cls(world.names, world.marker_height, scene_occluders(world.scenario),
                   world.marker_outline)

    def reset(self) -> None:
        self._in_view: list[np.ndarray] = []
        self._detected: list[np.ndarray] = []
        self._error: list[np.ndarray] = []
        self._heading: list[np.ndarray] = []
        self._identity: list[np.ndarray] = []

    def in_view(self, truth: np.ndarray, camera: np.ndarray | None) -> np.ndarray:
        """(n,) which robots at true poses `truth` (n, 3) no occluder hides from `camera`."""
        if not self.occluders or camera is None:
            return np.ones(len(truth), bool)
        return ~occluded(truth, self.marker_height, camera, self.occluders, self.outline)

    def add(self, detected: np.ndarray, poses: np.ndarray, truth: np.ndarray,
            camera: np.ndarray | None = None) -> None:
        """One processed frame: the tracker's flags (n,) and poses (n, 3) (NaN where missed),
        the true poses then (n, 3), and the camera's position (for occlusion by obstacles)."""
        if camera is not None:
            self.camera = np.asarray(camera, float)
        in_view = self.in_view(truth, camera)
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

    def report(self, log: PoseLog | None = None) -> TrackingHealth:
        """The figures so far; with the run's pose `log` (its tracker this monitor's chain),
        the detected and hidden shares of the rows it logged too: what a dataset holds."""
        n = len(self.names)
        rows = np.zeros(n, int)
        rows_hidden = np.zeros(n, int)
        row_share = np.full(n, math.nan)
        if log is not None and log.detected:
            truth = np.asarray(log.poses).reshape(-1, n, 3)
            flags = np.asarray(log.detected).reshape(-1, n)
            view = self.in_view(truth.reshape(-1, 3), self.camera).reshape(-1, n)   # one call
            rows, rows_hidden = view.sum(axis=0), (~view).sum(axis=0)
            with np.errstate(invalid="ignore"):
                row_share = (flags & view).sum(axis=0) / rows
        if not self._in_view:
            return TrackingHealth(tuple(
                RobotHealth(nm, 0, 0, math.nan, int(rows[i]), int(rows_hidden[i]),
                            float(row_share[i]), *[math.nan] * 8)
                for i, nm in enumerate(self.names)))
        in_view = np.array(self._in_view)
        det = np.array(self._detected)
        err = np.array(self._error) * 1000
        head = np.degrees(np.array(self._heading))
        ident = np.array(self._identity)
        robots = []
        for i, name in enumerate(self.names):
            frames = int(in_view[:, i].sum())
            e, h = err[det[:, i], i], head[det[:, i], i]
            q = np.percentile(e, [50, 95, 99]) if len(e) else [math.nan] * 3
            heading = ([float(np.median(h)), float(np.percentile(h, 99)),
                        float(np.mean(h > 30)), float(np.mean(h > 90))] if len(h)
                       else [math.nan] * 4)
            robots.append(RobotHealth(
                name, frames, int(len(in_view) - frames),
                float(det[:, i].sum() / frames) if frames else math.nan,
                int(rows[i]), int(rows_hidden[i]), float(row_share[i]),
                *(float(v) for v in q), *heading,
                float(ident[det[:, i], i].mean()) if len(e) else math.nan))
        return TrackingHealth(tuple(robots))
