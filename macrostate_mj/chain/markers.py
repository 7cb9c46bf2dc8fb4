"""The marker colour code, both sides of it: the colour each robot's marker gets, and which
colours the overhead tracker takes for which marker.

It lives in `chain`, below `vision`, so that loading a robot (`chain.robot`) can refuse a body
the tracker would take for a marker by the tracker's own rule, and `vision.tracker` classifies
pixels with this same code (one rule, never two copies that drift apart). Hues and thresholds are
OpenCV's 8-bit full-range HSV (`cv2.COLOR_RGB2HSV_FULL`): hue 0-255 around the circle,
saturation and value 0-255.
"""

from __future__ import annotations

import colorsys
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

import numpy as np

from macrostate_mj.core.errors import UserError

if TYPE_CHECKING:
    import mujoco

MIN_SATURATION = 90     # of 255: a greyer pixel is never any marker's
MIN_VALUE = 50          # of 255: a darker pixel is never any marker's
HUE_LEVELS = 256        # full-range hue: 0-255 around the circle
MAX_HUE_TOLERANCE = 14  # of 256: how far a marker's pixels may stray in hue (few robots)
# Teams over LEGACY_TEAM wear dimmer colours: a full-value colour clips under the lab's lights
# and its rendered hue drifts towards the nearest RGB primary or secondary (by ~9 of 256 levels,
# for hues between them); at value LARGE_TEAM_VALUE no channel clips. Teams up to LEGACY_TEAM
# keep their colours (the built-in scenarios' outputs, bit for bit).
LEGACY_TEAM = 5
LARGE_TEAM_VALUE = 0.7
# The most colour markers the classifier separates under the default imaging noise: the worst
# p99 hue stray of a rendered marker (thymio, e-puck, GRITSBot; docs: decisions) must fit in
# `hue_tolerance(n)`. Measured 11 levels (GRITSBot): hue_tolerance(10) = 11.
SEPARABLE_COLOURS = 10


class Markers(Protocol):
    """What each robot wears for the overhead tracker, as the world builder needs it (the
    tracker for each kind is chosen in `vision`, by this object's type)."""

    def check_team(self, n: int) -> None:
        """Refuse a team of n the tracker could not tell apart (one-line UserError)."""

    def colours(self, n: int) -> np.ndarray:
        """(n, 3) RGB in [0, 1]: each robot's marker colour (`World.colours`)."""

    def dress(self, spec: mujoco.MjSpec, names: list[str], colours: np.ndarray) -> None:
        """Put each robot's marker on its `{name}/marker` geom in the world's spec."""

    def colour_teams(self, capacity: int) -> int | None:
        """The largest colour team a robot's own colours must not be mistaken in (None: the
        markers have no colours to mistake)."""


@dataclass(frozen=True)
class ColourMarkers:
    """Each robot wears a flat triangle of its own colour (the dissertation's lab, Fig 2.6):
    the default marker kind (`[markers] kind = "colour"` in a scenario file)."""

    def check_team(self, n: int) -> None:
        if n > SEPARABLE_COLOURS:
            raise UserError(f"{n} colour markers are more than the tracker can tell apart under "
                            f"imaging noise (at most {SEPARABLE_COLOURS}); use [markers] kind = "
                            f'"aruco" for teams over {SEPARABLE_COLOURS}', "robots")

    def colours(self, n: int) -> np.ndarray:
        return marker_colours(n)

    def dress(self, spec: mujoco.MjSpec, names: list[str], colours: np.ndarray) -> None:
        for name, colour in zip(names, colours, strict=True):
            spec.geom(f"{name}/marker").rgba = [*colour, 1.0]

    def colour_teams(self, capacity: int) -> int | None:
        return min(capacity, SEPARABLE_COLOURS)

    @property
    def pattern(self) -> float:
        """The share of the marker's side the tracker needs in view: all of the triangle (a
        part hidden moves its centroid)."""
        return 1.0


def marker_colours(n: int) -> np.ndarray:
    """n saturated colours with hues spread evenly, so the tracker can tell them apart; dimmer
    for teams over LEGACY_TEAM, whose closer hues must not drift."""
    value = 1.0 if n <= LEGACY_TEAM else LARGE_TEAM_VALUE
    return np.array([colorsys.hsv_to_rgb(i / n, 1.0, value) for i in range(n)])


def marker_hues(colours: np.ndarray) -> np.ndarray:
    """Each marker colour's hue (int32, 0-255), the centre of the pixels taken for it."""
    hues = np.array([colorsys.rgb_to_hsv(*c)[0] for c in colours]) * HUE_LEVELS
    return hues.astype(np.int32) % HUE_LEVELS


def hue_tolerance(n: int) -> int:
    """How far (in hue levels) a pixel may be from a marker's hue and still count for it: half
    the gap between neighbouring hues less one, so no pixel counts for two markers."""
    spacing = HUE_LEVELS / max(n, 2)
    return int(min(MAX_HUE_TOLERANCE, spacing / 2 - 1))


def hue_distance(hue: np.ndarray, centre: int) -> np.ndarray:
    """Distance around the hue circle (levels) from `centre` to each of `hue` (ints)."""
    half = HUE_LEVELS // 2
    return np.abs((hue - centre + half) % HUE_LEVELS - half)


def marker_of_pixels(hsv: np.ndarray, colours: np.ndarray) -> np.ndarray:
    """(k,) the index of the marker among `colours` each pixel of `hsv` (k, 3), 8-bit full-range
    HSV (`cv2.COLOR_RGB2HSV_FULL`) counts for, or -1: the tracker's rule per pixel (saturation
    and value at least MIN_SATURATION and MIN_VALUE, hue within `hue_tolerance` of a marker's),
    for checks that judge rendered pixels as `vision.tracker` does."""
    hsv = np.asarray(hsv).reshape(-1, 3).astype(np.int32)
    near = hue_distance(np.arange(HUE_LEVELS)[:, None], marker_hues(colours)[None, :]) \
        <= hue_tolerance(len(colours))                          # (hue level, marker)
    marker_of_hue = np.where(near.any(axis=1), near.argmax(axis=1), -1)
    bright = (hsv[:, 1] >= MIN_SATURATION) & (hsv[:, 2] >= MIN_VALUE)
    return np.where(bright, marker_of_hue[hsv[:, 0] % HUE_LEVELS], -1)


def taken_for_marker(rgb: tuple[float, float, float] | np.ndarray,
                     colours: np.ndarray) -> int | None:
    """The index of the marker among `colours` that a surface of colour `rgb` (0-1) would be
    tracked as, or None: the tracker's rule (saturated and bright enough, hue within the
    tolerance of a marker's) applied to the colour as an 8-bit image holds it."""
    r, g, b = (round(float(c) * 255) / 255 for c in rgb[:3])
    h, s, v = colorsys.rgb_to_hsv(r, g, b)
    if round(s * 255) < MIN_SATURATION or round(v * 255) < MIN_VALUE:
        return None
    hue = np.array([round(h * HUE_LEVELS) % HUE_LEVELS])
    tol = hue_tolerance(len(colours))
    for i, centre in enumerate(marker_hues(colours)):
        if hue_distance(hue, int(centre))[0] <= tol:
            return i
    return None


def apex_behind(along: np.ndarray, across: np.ndarray) -> bool:
    """Does the triangle's apex lie on the negative side of its long axis, given its pixels'
    offsets from their centroid `along` the axis and `across` it? The base's half is the wider:
    pixels behind the centroid spread farther across than those ahead when the apex is ahead.
    Second moments, so a halo of blur or a stray pixel moves it less than the third moment
    along the axis did (that flipped 1-10 % of the e-puck lab's headings at the walls)."""
    ahead, behind = along > 0, along < 0
    if not (ahead.any() and behind.any()):
        return bool(np.mean(along**3) < 0)
    return bool(np.abs(across[ahead]).mean() > np.abs(across[behind]).mean())
