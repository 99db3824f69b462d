"""The fitted skeleton seen from the side, with the floor: a second viewpoint that shows what the image
cannot (how far the person leans toward the camera, whether they are up or on the floor).

The view looks along the camera's x axis (from the image's right edge toward its left): horizontal = depth z
(away from the camera, metres), vertical = up (-y of the camera frame; the camera is taken as level, as the
fit does). With a fit through the camera's own lens the joints are where the fit put them in the camera frame
(the camera is drawn at the left); without ``root_cam_m`` (an assumed lens, or an orthographic fit) only their
offsets from the mid-hip are known and the mid-hip is
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
CAMERA_IN_VIEW_M = 1.5   # a camera nearer than this to the clip's joints is drawn in the frame; else an arrow
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
        y_lo, y_hi = float(allp[:, 1].min()) - 0.15, max(float(allp[:, 1].max()), floor) + 0.02
        z_lo, z_hi = float(allp[:, 2].min()) - 0.4, float(allp[:, 2].max()) + 0.4
        if absolute and z_lo < CAMERA_IN_VIEW_M:
            z_lo = min(z_lo, -0.3)      # the camera close: drawn where it is (else an arrow points to it)
        if absolute:
            y_lo = min(y_lo, -0.2)      # the camera's height in view
        return cls((z_lo, z_hi), (y_lo, y_hi), floor, absolute, absolute and camera_height_m > 0)


TOP_PX = 60       # the title and the note (at 720 px high)
FLOOR_PX = 34     # the floor strip under the floor line, with its note


def render_side(joints: dict[str, np.ndarray] | None, frame: SideFrame, size: tuple[int, int],
                note: str = "") -> np.ndarray:
    """The side panel (BGR, ``size`` = (width, height)) for one frame's joints (camera frame or mid-hip
    relative, metres; None: no fit this frame). The clip's height range fills the panel between the title and
    a thin floor strip at the bottom, the floor line on the strip; when the clip's depth range is wider than
    the panel at that scale, the panel shows a window of it centred on the person (the grid says the
    distances). The camera is at the left: drawn where it is when the fit knows it and it is in view, else an
    arrow pointing to it."""
    w, h = size
    img = np.full((h, w, 3), BACKGROUND, np.uint8)
    s = max(h / 720.0, 0.6)
    top, bottom = TOP_PX * s, FLOOR_PX * s
    (z0, z1), (y0, y1) = frame.z_range, frame.y_range
    k = (h - top - bottom) / (y1 - y0)          # pixels per metre, same on both axes: the height filled
    if k * (z1 - z0) <= w - 40:                 # the clip's depth range fits: all of it, centred
        ox = 20 + ((w - 40) - k * (z1 - z0)) / 2
    else:                                       # it does not: a window of it that follows the person
        half = (w - 40) / (2 * k)
        zc = float(np.mean([float(p[2]) for p in joints.values()])) if joints else (z0 + z1) / 2
        z0 = min(max(zc, z0 + half), z1 - half) - half
        z1 = z0 + 2 * half
        ox = 20
    oy = (h - bottom) - k * (y1 - y0)           # the framing's bottom on the floor strip

    def to_px(p) -> tuple[float, float]:
        return ox + k * (float(p[2]) - z0), oy + k * (float(p[1]) - y0)

    # a 0.5 m grid, so distances can be read (labelled with the distance from the camera when it is known)
    for zg in np.arange(np.ceil(z0 * 2) / 2, z1, 0.5):
        x = ox + k * (zg - z0)
        cv2.line(img, (round(x), round(top)), (round(x), round(h - bottom)), (55, 55, 55), 1)
        if frame.camera_drawn and abs(zg - round(zg)) < 1e-6 and zg >= 0:
            draw.text(img, f"{zg:.0f} m", (x + 3 * s, top + 14 * s), 0.4 * s, (150, 150, 150), 1, background=None)
    if frame.floor_y is not None:
        yf = oy + k * (frame.floor_y - y0)
        cv2.rectangle(img, (0, round(yf)), (w, h), (70, 60, 50), -1)
        cv2.line(img, (0, round(yf)), (w, round(yf)), (180, 170, 150), max(1, round(2 * s)), cv2.LINE_AA)
        draw.text(img, frame.floor_note, (10 * s + 4, min(h - 8 * s, yf + 22 * s)), 0.45 * s,
                  (200, 200, 200), max(1, round(s)), background=None)
    grey = (200, 200, 200)
    cx, cy = to_px((0.0, 0.0, 0.0))
    if frame.camera_drawn and cx >= 10 * s:   # where the fit puts it
        pts = np.array([[cx, cy], [cx - 14 * s, cy - 9 * s], [cx - 14 * s, cy + 9 * s]], np.int32)
        cv2.fillPoly(img, [pts], grey, cv2.LINE_AA)
        draw.text(img, "camera", (cx - 14 * s, cy - 14 * s), 0.45 * s, grey, 1, background=None)
    else:   # further left than the panel, or its distance unknown: an arrow at the left edge pointing to it
        if not frame.camera_drawn:
            cy = top + (h - top - bottom) * 0.35
        cy = min(max(cy, top + 24 * s), h - bottom - 30 * s)
        x0 = 6 * s
        cv2.arrowedLine(img, (round(x0 + 40 * s), round(cy)), (round(x0), round(cy)), grey,
                        max(1, round(2 * s)), cv2.LINE_AA, tipLength=0.35)
        draw.text(img, "camera", (x0, cy - 10 * s), 0.45 * s, grey, 1, background=None)
        draw.text(img, f"(at 0 m, {z0:.1f} m left of the edge)" if frame.camera_drawn else "(distance unknown)",
                  (x0, cy + 22 * s), 0.4 * s, (160, 160, 160), 1, background=None)
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


def panel_width(frame: SideFrame, height: int) -> int:
    """A side panel width for ``height`` that fits the clip's framing at the height's scale (between 0.45 and
    0.8 of the height, and at least 360 px): a deep scene gets a wider panel (and beyond 0.8 a window that
    follows the person), never empty rows."""
    s = max(height / 720.0, 0.6)
    (z0, z1), (y0, y1) = frame.z_range, frame.y_range
    usable = height - (TOP_PX + FLOOR_PX) * s
    want = usable * (z1 - z0) / (y1 - y0) + 40
    return int(round(max(min(want, 0.8 * height), 0.45 * height, 360) / 2) * 2)
