"""A scenario's imaging noise: the parameters of what the camera chain does to each frame
(`vision/imaging.py` applies them). They live with the scenario, below the camera chain, so a
scenario file's `[noise]` table can set them and the scenario is checked whole when it is made.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

from macrostate_mj.core.errors import UserError


@dataclass(frozen=True)
class NoiseConfig:
    light_scale: tuple[float, float] = (0.75, 1.15)   # diffuse intensity multiplier range
    light_tilt_deg: float = 25.0                       # max tilt of the key light from vertical
    cam_shift_m: float = 0.0005                        # camera position error (sigma, m)
    cam_tilt_deg: float = 0.01                         # camera orientation error (sigma, deg)
    sensor_sigma: float = 3.0                          # Gaussian sensor noise (0-255 units)
    jpeg_quality: tuple[int, int] = (75, 95)
    blur_px: float = 1.5                               # max motion-blur length (px)
    psf_sigma_px: float = 0.4                          # lens point-spread function (Gaussian)
    drop_prob: float = 0.003                           # whole frames lost
    distortion_error: float = 0.0                      # calibrated k1, k2: relative error sigma

    def __post_init__(self) -> None:
        """Refuse NaN, negative values, empty ranges, a drop probability over 1 and JPEG
        qualities outside 1-100, naming the scenario file's key."""
        for f in fields(self):
            value = getattr(self, f.name)
            values = value if isinstance(value, tuple) else (value,)
            if not all(isinstance(v, int | float) and math.isfinite(v) and v >= 0
                       for v in values):
                raise UserError(f"noise.{f.name} must be finite and non-negative, got {value!r}",
                                f.name)
            if isinstance(value, tuple) and (len(value) != 2 or value[0] > value[1]):
                raise UserError(f"noise.{f.name} must be a range [low, high], got {value!r}",
                                f.name)
        if self.drop_prob > 1:
            raise UserError(f"noise.drop_prob is a probability, got {self.drop_prob:g}",
                            "drop_prob")
        if not (1 <= self.jpeg_quality[0] and self.jpeg_quality[1] <= 100):
            raise UserError(f"noise.jpeg_quality must lie in 1-100, got {self.jpeg_quality}",
                            "jpeg_quality")

    @classmethod
    def none(cls) -> NoiseConfig:
        """Clean frames: the tracker's own (quantization) limit."""
        return cls((1.0, 1.0), 0.0, 0.0, 0.0, 0.0, (100, 100), 0.0, 0.0, 0.0)
