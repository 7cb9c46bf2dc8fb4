"""Drawing primitives every diagnostic video shares (BGR uint8 frames, drawn in place)."""

from __future__ import annotations

import cv2
import numpy as np

INK, PAPER = (20, 20, 20), (245, 245, 245)   # BGR
FONT = cv2.FONT_HERSHEY_SIMPLEX


def label(bgr: np.ndarray, text: str, at: tuple[int, int], scale: float = 0.45,
          colour: tuple[int, int, int] = INK) -> None:
    """Text with its baseline at `at`, on a pale box: readable over any floor or robot."""
    (w, h), base = cv2.getTextSize(text, FONT, scale, 1)
    u, v = at
    cv2.rectangle(bgr, (u - 2, v - h - 2), (u + w + 2, v + base), PAPER, -1)
    cv2.putText(bgr, text, (u, v), FONT, scale, colour, 1, cv2.LINE_AA)


def box(bgr: np.ndarray, xywh: tuple[float, float, float, float], colour: tuple[int, int, int],
        text: str | None = None) -> None:
    """A rectangle (pixels, x y w h) with an optional caption above it."""
    x, y, w, h = (int(round(v)) for v in xywh)
    cv2.rectangle(bgr, (x, y), (x + w, y + h), colour, 1, cv2.LINE_AA)
    if text:
        label(bgr, text, (x, max(10, y - 3)), 0.35, colour)
