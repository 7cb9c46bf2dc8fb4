"""The team a recording shows, read from a sample of its frames, so that `track` can refuse a
`--robots` the footage contradicts before it tracks anything.

Why: colour markers are chosen by team size (`chain.markers.marker_colours`), so a 10-robot video
tracked as 8 robots finds every robot in every frame, three to five of them being their
neighbours; tags outside the team are ignored, so a 20-robot video tracked as 16 loses four
robots without a word. Neither shows in a detected share.

Tags: the ids the tracker's own detector decodes (any id of the dictionary) must lie in
0..n-1, and the highest ids of the team must appear. Colours: the marker-sized blobs of
saturated pixels (connected components of the tracker's saturation and value mask, MIN_AREA to
MAX_AREA times the marker's area in pixels) must each be claimed, by hue, by a robot of their
own, in most of the frames; a robot of the team whose colour appears in no frame while fewer
blobs show is a team the video does not hold either. The count named is the most frequent one.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence

import cv2
import mujoco
import numpy as np

from macrostate_mj.chain.markers import (
    HUE_LEVELS,
    MIN_SATURATION,
    MIN_VALUE,
    SEPARABLE_COLOURS,
    hue_distance,
    hue_tolerance,
    marker_colours,
    marker_hues,
)
from macrostate_mj.chain.tags import ArucoMarkers
from macrostate_mj.chain.world import World
from macrostate_mj.core.errors import UserError
from macrostate_mj.vision.aruco import ArucoTracker
from macrostate_mj.vision.camera import PinholeCamera

SAMPLES = 16        # frames looked at, spread over the video: a few seconds of decoding at most
MIN_AREA = 0.4      # a blob of under this share of a marker's area is a speck (the tracker's
#                     own `min_fill`: less than this never makes a detection)
MAX_AREA = 2.5      # over this many markers' area: a floor, a wall, an obstacle, not a marker
MIN_SIGHTINGS = 2   # a tag id decoded in fewer sampled frames may be a misread, not a robot


def check_team_shown(world: World, data: mujoco.MjData, frames: Sequence[np.ndarray],
                     source: str) -> None:
    """Refuse (one-line `UserError`) when the `frames` of `source` (RGB, the camera's size)
    show another team than the world's `len(world.names)` robots of its marker kind."""
    if not len(frames):
        return
    camera = PinholeCamera.from_model(world.model, data,
                                      distortion=world.scenario.camera.distortion)
    if isinstance(world.scenario.markers, ArucoMarkers):
        _check_tags(world, camera, frames, source)
    else:
        _check_colours(world, camera, frames, source)


def tag_ids_seen(world: World, camera: PinholeCamera, frames: Sequence[np.ndarray]) -> Counter:
    """In how many of `frames` each tag id of the world's dictionary is decoded (by the
    tracker's detector and settings, any id, hidden or not)."""
    markers = world.scenario.markers
    detector = ArucoTracker(camera, markers, markers.ids, world.marker_height, world.marker_area)
    seen: Counter = Counter()
    for rgb in frames:
        seen.update(np.flatnonzero(detector.track(rgb).detected).tolist())
    return seen


def _check_tags(world: World, camera: PinholeCamera, frames: Sequence[np.ndarray],
                source: str) -> None:
    n, k = len(world.names), len(frames)
    seen = tag_ids_seen(world, camera, frames)
    ids = sorted(i for i, c in seen.items() if c >= min(MIN_SIGHTINGS, k))
    if not ids:
        return          # nothing decodes: the track says which robots it missed, and why
    team = ids[-1] + 1
    outside = [i for i in ids if i >= n]
    if outside:
        raise UserError(f"{source} shows tags {_ranges(ids)} ({team} robots) in {k} sampled "
                        f"frames but --robots is {n}; give --robots {team} (tag id = place in "
                        "the chain)", "robots")
    if team < n and not any(seen[i] for i in range(team, n)):
        raise UserError(f"{source} shows tags {_ranges(ids)} ({team} robots) in {k} sampled "
                        f"frames and none of {_ranges(list(range(team, n)))}, but --robots is "
                        f"{n}; give --robots {team} (tag id = place in the chain)", "robots")


def _ranges(ids: list[int]) -> str:
    """Sorted ids as runs: [0, 1, 2, 5] -> '0-2, 5'."""
    runs: list[list[int]] = []
    for i in ids:
        if runs and i == runs[-1][1] + 1:
            runs[-1][1] = i
        else:
            runs.append([i, i])
    return ", ".join(f"{a}" if a == b else f"{a}-{b}" for a, b in runs)


def colour_blobs(rgb: np.ndarray, area_px: float) -> np.ndarray:
    """The hue (0-255) of each marker-sized blob of saturated, bright pixels in `rgb`: the
    tracker's mask (`chain.markers` thresholds), 8-connected components of MIN_AREA to MAX_AREA
    times `area_px`, each blob's hue the circular mean of its pixels'."""
    hsv = cv2.cvtColor(rgb, cv2.COLOR_RGB2HSV_FULL)
    mask = cv2.inRange(hsv, (0, MIN_SATURATION, MIN_VALUE), (255, 255, 255))
    count, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
    area = stats[:, cv2.CC_STAT_AREA]
    keep = np.flatnonzero((area >= MIN_AREA * area_px) & (area <= MAX_AREA * area_px))
    keep = keep[keep > 0]                                   # 0: the background
    if not len(keep):
        return np.empty(0, np.int64)
    on = mask > 0
    label = labels[on]
    angle = hsv[..., 0][on].astype(np.float64) * (2 * np.pi / HUE_LEVELS)
    c = np.bincount(label, np.cos(angle), count)[keep]
    s = np.bincount(label, np.sin(angle), count)[keep]
    return np.round(np.arctan2(s, c) * HUE_LEVELS / (2 * np.pi)).astype(np.int64) % HUE_LEVELS


def claims(hues: np.ndarray, n: int) -> np.ndarray:
    """(k,) the robot of a team of n whose colour claims each blob hue (the tracker's hue
    tolerance), -1 where none does."""
    centres = marker_hues(marker_colours(n))
    dist = np.stack([hue_distance(hues, int(c)) for c in centres], axis=1)    # (k, n)
    return np.where(dist.min(axis=1) <= hue_tolerance(n), dist.argmin(axis=1), -1) \
        if len(hues) else np.empty(0, np.int64)


def fits(hues: np.ndarray, n: int) -> bool:
    """Whether a frame's blob hues are markers of a team of n: each claimed, none twice."""
    who = claims(hues, n)
    return bool(np.all(who >= 0) and len(set(who.tolist())) == len(who))


def _check_colours(world: World, camera: PinholeCamera, frames: Sequence[np.ndarray],
                   source: str) -> None:
    n, k = len(world.names), len(frames)
    scale = camera.focal / (camera.position[2] - world.marker_height)
    area_px = world.marker_area * scale**2                  # as `vision.tracker.Tracker`
    blobs = [colour_blobs(rgb, area_px) for rgb in frames]
    counts = Counter(len(b) for b in blobs)
    shown = max(counts, key=lambda c: (counts[c], c))       # the most frequent; ties: more
    if not shown:
        return          # no marker shows: the track says which robots it missed, and why
    fix = (f"give --robots {shown} (colour markers are chosen by team size)"
           if 2 <= shown <= SEPARABLE_COLOURS and shown != n and
           sum(fits(b, shown) for b in blobs) > k / 2 else
           "give the team size filmed (colour markers are chosen by team size) or the "
           "scenario of its lab")
    said = (f"{source} shows {shown} colour markers (the most frequent count in {k} sampled "
            f"frames)")
    bad = [b for b in blobs if not fits(b, n)]
    if len(bad) > k / 2:
        who = [claims(b, n) for b in bad]
        twice = sum(len(set(w.tolist()) - {-1}) < int((w >= 0).sum()) for w in who)
        what = (f"in {twice} of them two markers wear one robot's colour"
                if twice >= len(bad) / 2 else
                f"in {len(bad) - twice} of them a marker wears a colour no robot of {n} wears")
        raise UserError(f"{said} but --robots is {n}: {what}; {fix}", "robots")
    claimed = set().union(*(set(claims(b, n).tolist()) for b in blobs))
    never = [world.names[i] for i in range(n) if i not in claimed]
    if shown < n and never:          # every blob fits this team too: a robot may be unseen
        raise UserError(f"{said} but --robots is {n}: the colour of {', '.join(never)} shows "
                        f"in none of them; {fix} if {shown} robots were filmed (if "
                        f"{', '.join(never)} stood hidden or out of the frame throughout, the "
                        f"footage shows too little of the team to track)", "robots")
