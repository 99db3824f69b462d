"""A rendered frame: the camera image with the landmarks, the reprojected fit and the angles (``overlay``),
and beside it the side view of the fitted skeleton (``side_view``)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from posed.camera_model import Intrinsics
from posed.viz import overlay, posture
from posed.viz.overlay import FrameInfo
from posed.viz.reproject import camera_joints, reproject
from posed.viz.side_view import SideFrame, panel_width, render_side

BLANK = (90, 90, 90)   # the background when there is no source video (a landmark recording alone)


@dataclass(frozen=True)
class FrameInput:
    """One frame to draw. ``result``: the fit's JSON-derived ``fitting.FitResult`` or None (no fit)."""

    seq: int
    t: float
    landmarks: np.ndarray | None     # 33 x 5 [x_px, y_px, z, visibility, presence]
    result: object | None            # fitting.FitResult
    fall_state: str | None = None
    fall_event: str | None = None
    person: int | None = None        # several people: the track id of the person whose angles are shown
    others: tuple = ()               # the other people: (track id, 33 x 5 landmarks, FitResult or None) each


def joints_for_side(result, absolute: bool) -> dict[str, np.ndarray] | None:
    """The measured joints the side view draws (``FitResult.measured_joints``: a joint whose landmark the
    frame did not see is left out): camera-frame when ``absolute`` (root known), else mid-hip relative."""
    if result is None or not result.ok or not result.measured_joints():
        return None
    measured = result.measured_joints()
    root = result.root_cam_m
    if absolute and root is not None:
        return camera_joints(measured, root)
    joints = {k: np.asarray(v, float) for k, v in measured.items()}
    lowest = max(float(v[1]) for v in joints.values())     # y is down: stand the lowest joint on y = 0
    return {k: v - np.array([0.0, lowest, 0.0]) for k, v in joints.items()}


def trunk_lean_deg(result) -> float | None:
    """How far the trunk (mid-hip to mid-shoulder) leans from the vertical, degrees: against the gravity the fit
    was given (the result's ``down``, fitting.vertical), else the camera taken as level (its y axis vertical);
    None when the frame did not measure the torso. Trunk flexion is measured against the pelvis, so a person
    lying straight on the floor has none: this says they are lying."""
    if "theta_tr" not in result.measured.angles:
        return None
    j = result.joints_3d
    try:
        up = (np.asarray(j["left_shoulder"], float) + np.asarray(j["right_shoulder"], float)) / 2 \
            - np.asarray(j["mid_hip"], float)
    except KeyError:
        return None
    given = result.extra.get("down")
    down = None if given is None else posture.valid_down(given)
    if given is not None and down is None:
        return None
    lean = posture.incline_deg(up, down)
    return lean if math.isfinite(lean) else None


class ClipRenderer:
    """Draws the frames of one clip at a fixed layout: image (W x H) + side panel (``side_width`` x H)."""

    def __init__(self, image_size: tuple[int, int], intrinsics: Intrinsics | None, results: Sequence,
                 side_width: int | None = None, camera_height_m: float = 0.0) -> None:
        self.image_size = (int(image_size[0]), int(image_size[1]))
        self.intrinsics = intrinsics
        ok = [r for r in results if r is not None and r.ok]
        self.absolute = bool(ok) and intrinsics is not None and all(r.root_cam_m is not None for r in ok)
        self.side = SideFrame.for_clip([joints_for_side(r, self.absolute) or {} for r in ok], self.absolute,
                                       camera_height_m)
        h = self.image_size[1]
        self.side_width = side_width or panel_width(self.side, h)

    @property
    def size(self) -> tuple[int, int]:
        return (self.image_size[0] + self.side_width, self.image_size[1])

    def frame(self, image: np.ndarray | None, item: FrameInput) -> np.ndarray:
        w, h = self.image_size
        canvas = np.full((h, w, 3), BLANK, np.uint8) if image is None else image.copy()
        result = item.result
        reproj = None
        angles: dict[str, float] = {}
        note = ""
        lean = None
        evidence: tuple[str, ...] = ()
        lens = None
        if result is not None and result.ok:
            # only what the frame measured (fitting.measured): an unseen limb is the model's guess
            reproj = reproject(result.measured_joints(), result.root_cam_m, self.intrinsics, item.landmarks)
            angles = result.measured_angles()
            lean = trunk_lean_deg(result)
            evidence = tuple(result.extra.get("evidence", ()))
            lens = result.extra.get("lens")
        elif result is not None:
            note = result.reason or "fit failed"
        elif item.landmarks is None:
            note = "no person"
        for pid, lms, res in item.others:      # several people: each drawn and labelled; the angles are one's
            overlay.draw_landmarks(canvas, lms)
            if res is not None and res.ok:
                overlay.draw_model(canvas, reproject(res.measured_joints(), res.root_cam_m, self.intrinsics, lms))
            overlay.draw_person_label(canvas, lms, f"person {pid}")
        overlay.draw_landmarks(canvas, item.landmarks)
        overlay.draw_model(canvas, reproj)
        if item.person is not None:
            overlay.draw_person_label(canvas, item.landmarks, f"person {item.person} (angles)")
        overlay.draw_info(canvas, FrameInfo(item.t, angles, note, item.fall_state, item.fall_event,
                                            reproj.how if reproj else "", lean, evidence, lens))
        overlay.legend(canvas)
        side = render_side(joints_for_side(result, self.absolute), self.side, (self.side_width, h),
                           "" if self.absolute else "depth relative to the hips (no camera intrinsics)")
        return np.concatenate([canvas, side], axis=1)
