"""What a tracked run must meet: a scenario's `[tracking]` table.

Every tracked run compares what the tracker reported with the truth the simulator knows
(`vision.health`); these limits say when that comparison ends the run (exit 1, outputs kept)
instead of handing over poses that are wrong without a word. Realistic noise (marker jitter,
dropped frames, blur) is not judged here: the figures are the tracker's own error.

A pose is position, heading and identity, so each has its limits. Distances are millimetres and
shares fractions of 1, each with a range that a value in another unit cannot pass (3 mm typed
as 0.003, a metre's 0.01 for 10 mm, 95 for 95 %): the check is never silently off.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

from macrostate_mj.core.errors import UserError

# Per limit: its unit's words and the range a value in that unit can take (a share is 0..1;
# distances from a tenth of a millimetre, which no tracker reaches, to half a metre).
RANGES: dict[str, tuple[str, float, float]] = {
    "share": ("a share in [0, 1]", 0.0, 1.0),
    "mm": ("millimetres in [0.1, 500]", 0.1, 500.0),
}


@dataclass(frozen=True)
class TrackingLimits:
    """Defaults pass the built-in labs (docs: how-to/tracking-health) and fail a robot seen in
    fewer than 90 % of the dataset's rows where it is in view, hidden by an obstacle in more
    than 10 % of them, tracked more than 3 mm off at the median or 20 mm at the 99th percentile,
    headed more than 30 degrees off in 5 % of its detections or more than 90 degrees (flipped)
    in 1 %, or taken for another robot in 1 % of them."""

    min_detected: float = 0.9            # share of the dataset's rows where it is in view
    max_hidden: float = 0.1              # share of the rows in which an obstacle hides it
    max_median_mm: float = 3.0           # the median tracked-position error
    max_p99_mm: float = 20.0             # its 99th percentile
    max_heading_off30: float = 0.05      # share of detections whose heading errs > 30 deg
    max_heading_flips: float = 0.01      # share of detections whose heading errs > 90 deg
    max_identity_errors: float = 0.01    # share of detections nearer another robot's truth

    def __post_init__(self) -> None:
        """Out-of-range limits are refused, naming the scenario file's key and its unit."""
        for key in (f.name for f in fields(self)):
            words, lo, hi = RANGES[unit(key)]
            v = getattr(self, key)
            if isinstance(v, bool) or not isinstance(v, int | float) or not lo <= v <= hi:
                raise UserError(f"tracking.{key} must be {words}, got {v!r}{_hint(key, v)}",
                                key)
            if key.startswith("max_") and unit(key) == "share" and v == 1:
                raise UserError(f"tracking.{key} = 1 is 100 %, a limit that judges nothing; "
                                "for 1 % write 0.01", key)

    def describe(self) -> str:
        """The limits in one line, in their units (what `scenario check` prints)."""
        def show(key: str) -> str:
            v = getattr(self, key)
            return f"{v:g} mm" if unit(key) == "mm" else f"{v:.0%}"

        return ", ".join(f"{f.name} {show(f.name)}" for f in fields(self))


def unit(key: str) -> str:
    """A limit's unit, by its name: `*_mm` millimetres, else a share."""
    return "mm" if key.endswith("_mm") else "share"


def _hint(key: str, v: object) -> str:
    """The value in the unit it was likely meant in: a percentage for a share, metres for
    millimetres."""
    if isinstance(v, bool) or not isinstance(v, int | float):
        return ""
    if unit(key) == "share" and 1 < v <= 100:
        return f" (for {v:g} % write {v / 100:g})"
    if unit(key) == "mm" and 0 < v < RANGES["mm"][1]:
        return f" (for {v:g} m write {v * 1000:g})"
    return ""
