"""The fitted skeleton seen from the side, with the floor: a second viewpoint that shows what the image
cannot (how far the person leans toward the camera, whether they are up or on the floor).

The view looks along the camera's x axis (from the image's right edge toward its left): horizontal = depth z
(away from the camera, metres), vertical = up (-y of the camera frame; the camera is taken as level, as the
fit does). With a perspective fit the joints are where the fit put them in the camera frame (the camera is
drawn at the left); with an orthographic fit only their offsets from the mid-hip are known and the mid-hip is
drawn at a fixed depth, and each frame is shifted so its lowest joint stands on the floor (a squat then
shows as the hips going down). The floor is ``ANKLE_HEIGHT_M`` below the lowest joint of the whole clip (the
ankle's height above the sole): an estimate from the person, not a measured plane.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from posed.viz import draw
from posed.viz.skeleton import MODEL_BONES, with_mid_shoulder

ANKLE_HEIGHT_M = 0.08
BACKGROUND = (32, 32, 32)


@dataclass(frozen=True)
class SideFrame:
    """The side view's fixed framing for a clip: camera-frame ranges (metres) and the floor's y."""

    z_range: tuple[float, float]
    y_range: tuple[float, float]     # y of the camera frame (down), top .. bottom of the picture
    floor_y: float | None
    camera_drawn: bool               # the camera's position (z = 0) is known and in view

    @property
    def floor_note(self) -> str:
        return "floor (the given camera height below the camera)" if self.camera_drawn and self.floor_from_config \
            else "floor (estimated: below the lowest joint)"

    floor_from_config: bool = False

    @classmethod
    def for_clip(cls, joint_sets: list[dict[str, np.ndarray]], absolute: bool,
                 camera_height_m: float = 0.0) -> SideFrame:
        """The framing that holds every joint of the clip (``absolute``: camera-frame positions; then a
        known ``camera_height_m`` > 0 places the floor, the camera being level)."""
        pts = [np.asarray(list(j.values()), float) for j in joint_sets if j]
        if not pts:
            return cls((-1.0, 1.0), (-1.2, 1.0), None, False)
        allp = np.concatenate(pts)
        floor = float(allp[:, 1].max()) + ANKLE_HEIGHT_M
        if absolute and camera_height_m > 0:
            floor = camera_height_m
        y_lo, y_hi = float(allp[:, 1].min()) - 0.25, max(float(allp[:, 1].max()), floor or -1e9) + 0.2
        z_lo, z_hi = float(allp[:, 2].min()) - 0.4, float(allp[:, 2].max()) + 0.4
        if absolute:
            z_lo = min(z_lo, -0.15)
        return cls((z_lo, z_hi), (y_lo, y_hi), floor, absolute, absolute and camera_height_m > 0)


def render_side(joints: dict[str, np.ndarray] | None, frame: SideFrame, size: tuple[int, int],
                note: str = "") -> np.ndarray:
    """The side panel (BGR, ``size`` = (width, height)) for one frame's joints (camera frame or mid-hip
    relative, metres; None: no fit this frame)."""
    w, h = size
    img = np.full((h, w, 3), BACKGROUND, np.uint8)
    s = max(h / 720.0, 0.6)
    (z0, z1), (y0, y1) = frame.z_range, frame.y_range
    k = min((w - 40) / (z1 - z0), (h - 90) / (y1 - y0))      # pixels per metre, same on both axes
    ox = 20 + ((w - 40) - k * (z1 - z0)) / 2
    oy = 60 + ((h - 90) - k * (y1 - y0)) / 2

    def to_px(p) -> tuple[float, float]:
        return ox + k * (float(p[2]) - z0), oy + k * (float(p[1]) - y0)

    # a 0.5 m grid, so distances can be read
    for zg in np.arange(np.ceil(z0 * 2) / 2, z1, 0.5):
        x = ox + k * (zg - z0)
        cv2.line(img, (round(x), round(oy)), (round(x), round(oy + k * (y1 - y0))), (55, 55, 55), 1)
    if frame.floor_y is not None:
        yf = oy + k * (frame.floor_y - y0)
        cv2.rectangle(img, (0, round(yf)), (w, h), (70, 60, 50), -1)
        cv2.line(img, (0, round(yf)), (w, round(yf)), (180, 170, 150), max(1, round(2 * s)), cv2.LINE_AA)
        draw.text(img, frame.floor_note, (10 * s + 4, yf + 22 * s), 0.45 * s,
                  (200, 200, 200), max(1, round(s)), background=None)
    if frame.camera_drawn:
        cx, cy = to_px((0.0, 0.0, 0.0))
        pts = np.array([[cx, cy], [cx - 14 * s, cy - 9 * s], [cx - 14 * s, cy + 9 * s]], np.int32)
        cv2.fillPoly(img, [pts], (200, 200, 200), cv2.LINE_AA)
        draw.text(img, "camera", (cx - 14 * s, cy - 14 * s), 0.45 * s, (200, 200, 200), 1, background=None)
    if joints:
        j = with_mid_shoulder({n: tuple(v) for n, v in joints.items()})
        # the far side (right, for a person facing the camera seen from the image right) drawn first
        for a, b, side in sorted(MODEL_BONES, key=lambda e: {"r": 0, "c": 1, "l": 2}[e[2]]):
            if a in j and b in j:
                draw.bone(img, to_px(j[a]), to_px(j[b]), side, max(2, round(4 * s)))
        for name, p in j.items():
            if name != "mid_shoulder":
                cv2.circle(img, tuple(round(c) for c in to_px(p)), max(3, round(4 * s)), (230, 230, 230), -1,
                           cv2.LINE_AA)
    draw.text(img, "side view (seen from the image's right)", (10 * s + 4, 24 * s), 0.5 * s,
              (235, 235, 235), max(1, round(s)), background=None)
    draw.text(img, note or "camera <- depth ->", (10 * s + 4, 46 * s), 0.42 * s, (180, 180, 180),
              max(1, round(s)), background=None)
    return img
