"""Small OpenCV drawing helpers shared by the overlay and the side view (BGR, pixels, anti-aliased)."""

from __future__ import annotations

import cv2
import numpy as np

# left and right are told apart by line style (right dashed) as well as by colour
LEFT = (0, 140, 255)     # orange
RIGHT = (255, 160, 0)    # blue
CENTRE = (60, 220, 60)   # green
SIDE_COLOUR = {"l": LEFT, "r": RIGHT, "c": CENTRE}
FONT = cv2.FONT_HERSHEY_SIMPLEX


def _pt(p) -> tuple[int, int]:
    return int(round(float(p[0]))), int(round(float(p[1])))


def line(img: np.ndarray, p0, p1, colour, thickness: int, dashed: bool = False) -> None:
    """A line from ``p0`` to ``p1``; ``dashed``: dashes about four line widths long."""
    if not dashed:
        cv2.line(img, _pt(p0), _pt(p1), colour, thickness, cv2.LINE_AA)
        return
    a, b = np.asarray(p0, float), np.asarray(p1, float)
    length = float(np.hypot(*(b - a)))
    dash = max(6.0, 4.0 * thickness)
    n = max(1, int(length // dash))
    for i in range(0, n, 2):
        cv2.line(img, _pt(a + (b - a) * i / n), _pt(a + (b - a) * min(i + 1, n) / n), colour, thickness,
                 cv2.LINE_AA)


def bone(img: np.ndarray, p0, p1, side: str, thickness: int) -> None:
    """A bone in its side's colour; the right side dashed (readable without colour)."""
    line(img, p0, p1, SIDE_COLOUR[side], thickness, dashed=(side == "r"))


def text(img: np.ndarray, s: str, org, scale: float, colour=(255, 255, 255), thickness: int = 1,
         background: tuple[int, int, int] | None = (0, 0, 0)) -> int:
    """``s`` with its baseline-left at ``org``, on a dark box; returns the line height in pixels."""
    (w, h), base = cv2.getTextSize(s, FONT, scale, thickness)
    x, y = _pt(org)
    if background is not None:
        x0, y0, x1, y1 = max(x - 3, 0), max(y - h - 4, 0), min(x + w + 3, img.shape[1]), min(y + base + 2,
                                                                                            img.shape[0])
        roi = img[y0:y1, x0:x1]
        if roi.size:
            roi[:] = (roi * 0.35 + np.asarray(background) * 0.65).astype(np.uint8)
    cv2.putText(img, s, (x, y), FONT, scale, colour, thickness, cv2.LINE_AA)
    return h + base + 6
