"""One frame of the overlay video: the 33 landmarks, the reprojected fitted skeleton, the main joint angles
by plain name and the fall detector's state, drawn on the camera image (BGR, its own pixels)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from posed.viz import draw
from posed.viz.names import MAIN_ANGLES, evidence_text, short_label
from posed.viz.reproject import Reprojection
from posed.viz.skeleton import LANDMARK_BONES, MODEL_BONES, with_mid_shoulder

MIN_VISIBILITY = 0.3   # landmarks less visible than this are drawn hollow and without bones (the fit drops them)
FALL_COLOURS = {"up": (60, 180, 60), "falling": (0, 165, 255), "on_floor": (0, 0, 230), "down": (0, 0, 230),
                "alarm": (0, 0, 255), "recovered": (60, 180, 60)}


@dataclass(frozen=True)
class FrameInfo:
    """What is written on a frame besides the drawings."""

    t: float                       # capture time, seconds
    angles: dict[str, float]       # joint angles, degrees (absent: not measured this frame)
    fit_note: str = ""             # "" or why there is no fit (the fit's reason)
    fall_state: str | None = None  # the detector's state (None: no detector ran)
    fall_event: str | None = None  # the last event message's state, e.g. "on_floor"
    how: str = ""                  # how the skeleton was reprojected
    trunk_lean: float | None = None  # the trunk's lean from the vertical, degrees (None: not measured)
    evidence: tuple[str, ...] = ()   # what the fit used (FitResult.extra["evidence"]; () when not said)
    lens: str | None = None          # the fit's lens (FitResult.extra["lens"]: given, assumed; None: not said)


def scale_of(img: np.ndarray) -> float:
    """Drawing scale: 1.0 for a 640 px short side."""
    return min(img.shape[:2]) / 640.0


def draw_landmarks(img: np.ndarray, landmarks: np.ndarray | None) -> None:
    """The 33 BlazePose landmarks (thin bones, small dots; hollow when hardly visible)."""
    if landmarks is None:
        return
    s = scale_of(img)
    lm = np.asarray(landmarks, float)
    vis = lm[:, 3] if lm.shape[1] > 3 else np.ones(len(lm))
    ok = np.all(np.isfinite(lm[:, :2]), axis=1) & (np.nan_to_num(vis, nan=0.0) >= MIN_VISIBILITY)
    for a, b, _side in LANDMARK_BONES:
        if ok[a] and ok[b]:
            draw.line(img, lm[a, :2], lm[b, :2], (235, 235, 235), max(1, round(1.2 * s)))
    r = max(2, round(3 * s))
    for i in range(len(lm)):
        if not np.all(np.isfinite(lm[i, :2])):
            continue
        p = (int(round(lm[i, 0])), int(round(lm[i, 1])))
        cv2.circle(img, p, r, (255, 255, 255), -1 if ok[i] else 1, cv2.LINE_AA)
        if ok[i]:
            cv2.circle(img, p, r, (40, 40, 40), 1, cv2.LINE_AA)


def draw_person_label(img: np.ndarray, landmarks: np.ndarray | None, text: str) -> None:
    """``text`` (a person's track id, whose angles are shown) above the person's landmark box."""
    if landmarks is None:
        return
    lm = np.asarray(landmarks, float)
    ok = np.all(np.isfinite(lm[:, :2]), axis=1)
    if not ok.any():
        return
    s = scale_of(img)
    x = int(np.clip(lm[ok, 0].min(), 0, img.shape[1] - 10))
    y = int(np.clip(lm[ok, 1].min() - 10 * s, 18 * s, img.shape[0] - 4))
    draw.text(img, text, (x, y), 0.5 * s, (255, 255, 255), max(1, round(1.2 * s)), background=(60, 60, 60))


def draw_model(img: np.ndarray, reproj: Reprojection | None) -> None:
    """The fitted skeleton (thick; left orange solid, right blue dashed, centre green): the joints in
    ``reproj`` only (the caller passes the measured ones), a bone where both its ends are there."""
    if reproj is None:
        return
    s = scale_of(img)
    px = with_mid_shoulder({k: (*v, 0.0) for k, v in reproj.pixels.items()})
    for a, b, side in MODEL_BONES:
        if a in px and b in px:
            draw.bone(img, px[a][:2], px[b][:2], side, max(2, round(4 * s)))
    for name, (u, v, _) in px.items():
        if name != "mid_shoulder":
            cv2.circle(img, (int(round(u)), int(round(v))), max(3, round(5 * s)), (20, 20, 20), -1, cv2.LINE_AA)


def draw_info(img: np.ndarray, info: FrameInfo) -> None:
    """The main joint angles by plain name (top left), the time, the fall state (top right)."""
    s = scale_of(img)
    fs = 0.55 * s
    th = max(1, round(1.3 * s))
    x, y = round(10 * s), round(26 * s)
    y += draw.text(img, f"t = {info.t:7.2f} s", (x, y), fs, thickness=th)
    if info.fit_note:
        y += draw.text(img, f"no fit: {info.fit_note[:48]}", (x, y), fs, (120, 200, 255), th)
    for name in MAIN_ANGLES:
        v = info.angles.get(name)
        shown = "not seen" if v is None or not math.isfinite(v) else f"{v:5.0f} deg"
        colour = {"left": draw.LEFT, "right": draw.RIGHT}.get(short_label(name).split()[0], (255, 255, 255))
        y += draw.text(img, f"{short_label(name):<22}{shown}", (x, y), fs, colour, th)
    if not info.fit_note:
        lean = "not seen" if info.trunk_lean is None else f"{info.trunk_lean:5.0f} deg"
        y += draw.text(img, f"{'trunk from vertical':<22}{lean}", (x, y), fs, thickness=th)
        if info.evidence:
            y += draw.text(img, evidence_text(info.evidence, info.lens), (x, y), 0.8 * fs, (220, 220, 220), th)
    if info.fall_state is not None:
        state = info.fall_event if info.fall_event and info.fall_state != "up" else info.fall_state
        words = {"up": "no fall", "down": "FALL detected", "alarm": "FALL: ALARM"}.get(info.fall_state,
                                                                                            info.fall_state)
        if info.fall_event and info.fall_state != "up":
            words += f" ({info.fall_event})"
        (w, _), _ = cv2.getTextSize(words, draw.FONT, 0.8 * s, th + 1)
        draw.text(img, words, (img.shape[1] - w - round(12 * s), round(34 * s)), 0.8 * s,
                  (255, 255, 255), th + 1, background=FALL_COLOURS.get(state, (80, 80, 80)))
    if info.how:
        draw.text(img, f"fitted skeleton: {info.how}", (x, img.shape[0] - round(12 * s)), 0.45 * s,
                  (220, 220, 220), max(1, round(s)))


def legend(img: np.ndarray) -> None:
    """A key to the lines, bottom right."""
    s = scale_of(img)
    fs, th = 0.45 * s, max(1, round(s))
    x0 = img.shape[1] - round(250 * s)
    y = img.shape[0] - round(80 * s)
    for text, side in (("fitted, left side", "l"), ("fitted, right side", "r")):
        draw.bone(img, (x0, y - 5 * s), (x0 + 40 * s, y - 5 * s), side, max(2, round(4 * s)))
        draw.text(img, text, (x0 + 50 * s, y), fs, thickness=th)
        y += round(22 * s)
    draw.line(img, (x0, y - 5 * s), (x0 + 40 * s, y - 5 * s), (235, 235, 235), max(1, round(1.2 * s)))
    draw.text(img, "BlazePose landmarks", (x0 + 50 * s, y), fs, thickness=th)
