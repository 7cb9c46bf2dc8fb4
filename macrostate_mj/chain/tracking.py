"""What a tracked run must meet: a scenario's `[tracking]` table.

Every tracked run compares what the tracker reported with the truth the simulator knows
(`vision.health`); these limits say when that comparison ends the run (exit 1, outputs kept)
instead of handing over poses that are wrong without a word. Realistic noise (marker jitter,
dropped frames, blur) is not judged here: the figures are the tracker's own error.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from macrostate_mj.core.errors import UserError


@dataclass(frozen=True)
class TrackingLimits:
    """Defaults: a robot seen in fewer than 90 % of the frames where it is in view, a median
    position error above 1 cm, or identity errors in more than 1 % of the frames fail a run."""

    min_detected: float = 0.9           # share of the frames where the robot is in view
    max_median_error: float = 0.01      # m: the median tracked-position error
    max_identity_errors: float = 0.01   # share of frames whose pose is nearer another robot

    def __post_init__(self) -> None:
        """Out-of-range limits are refused, naming the scenario file's key."""
        for key, hi in (("min_detected", 1.0), ("max_identity_errors", 1.0),
                        ("max_median_error", math.inf)):
            v = getattr(self, key)
            if isinstance(v, bool) or not (isinstance(v, int | float) and 0 <= v <= hi) \
                    or math.isnan(v) or (key == "max_median_error" and not 0 < v < math.inf):
                what = ("a share in [0, 1]" if hi == 1.0 else
                        "a positive finite distance in metres")
                raise UserError(f"tracking.{key} must be {what}, got {v!r}", key)
