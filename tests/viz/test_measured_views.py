"""What a frame did not measure is not drawn or stored as a fact (fitting.measured): the overlay and the side
view leave an unseen limb out, the history stores NULL for it; the trunk's lean from the vertical says
"lying" where trunk flexion (against the pelvis) cannot. And the views read: the side view fills its height,
shows where the camera is, and writing a .webm leaves no OpenCV FFMPEG note on standard error."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from posed.camera_model import Intrinsics
from posed.daemon.history.store import ANGLE_COLUMNS, AngleHistory
from posed.falls.config import FallsConfig
from posed.fitting import BODY_LANDMARK_NAMES, FitResult, Measured
from posed.viz import draw
from posed.viz.render import BLANK, ClipRenderer, FrameInput, trunk_lean_deg
from posed.viz.side_view import FLOOR_PX, TOP_PX, SideFrame, render_side
from posed.viz.video import VideoOut

K = Intrinsics(500.0, 500.0, 320.0, 240.0, 640, 480)
STANDING = {   # metres, mid-hip origin, camera axes (y down); arms out to the sides, well apart from the rest
    "mid_hip": (0.0, 0.0, 0.0), "left_hip": (0.1, 0.0, 0.0), "right_hip": (-0.1, 0.0, 0.0),
    "left_shoulder": (0.18, -0.5, 0.0), "right_shoulder": (-0.18, -0.5, 0.0),
    "left_elbow": (0.45, -0.5, 0.0), "right_elbow": (-0.45, -0.5, 0.0),
    "left_wrist": (0.7, -0.5, 0.0), "right_wrist": (-0.7, -0.5, 0.0),
    "left_knee": (0.1, 0.45, 0.0), "right_knee": (-0.1, 0.45, 0.0),
    "left_ankle": (0.1, 0.88, 0.0), "right_ankle": (-0.1, 0.88, 0.0)}


def _result(seen, joints=STANDING, root=(0.0, 0.0, 3.0), **extra):
    return FitResult(0, 0.0, True, joint_angles_deg={"theta_el_l": 90.0, "theta_kn_l": 5.0, "theta_tr": 0.0},
                     joints_3d=joints, extra={"root_cam_m": list(root), **extra},
                     measured=Measured.from_landmarks(seen))


def _near(img, uv, colour, r=5) -> int:
    u, v = int(round(uv[0])), int(round(uv[1]))
    patch = img[max(v - r, 0):v + r + 1, max(u - r, 0):u + r + 1].astype(int)
    return int(np.sum(np.abs(patch - np.array(colour)).sum(axis=2) < 60))


def _along(img, a, b, colour) -> int:
    return sum(_near(img, a + (b - a) * f, colour, r=3) for f in np.linspace(0.2, 0.8, 7))


def test_the_overlay_leaves_out_the_limb_the_frame_did_not_see():
    seen = set(BODY_LANDMARK_NAMES) - {"left_elbow"}
    renderer = ClipRenderer((640, 480), K, [_result(seen)])
    frame = renderer.frame(None, FrameInput(0, 0.0, None, _result(seen)))[:, :640]
    px = {n: K.project(np.array([p]) + np.array([0.0, 0.0, 3.0]))[0] for n, p in STANDING.items()}
    assert _along(frame, px["right_shoulder"], px["right_elbow"], draw.RIGHT) > 0     # the seen arm is drawn
    assert _along(frame, px["left_hip"], px["left_knee"], draw.LEFT) > 0
    assert _along(frame, px["left_shoulder"], px["left_elbow"], draw.LEFT) == 0       # the unseen one is not
    assert _along(frame, px["left_elbow"], px["left_wrist"], draw.LEFT) == 0
    assert _near(frame, px["left_elbow"], (20, 20, 20)) == 0               # nor its joint
    assert _near(frame, px["left_wrist"], (20, 20, 20)) > 0                # the wrist was seen: its dot is there
    untouched = frame[int(px["left_elbow"][1]) - 3:int(px["left_elbow"][1]) + 4,
                      int(px["left_elbow"][0]) - 3:int(px["left_elbow"][0]) + 4]
    assert (untouched == np.array(BLANK)).all()


def test_the_trunk_lean_tells_lying_from_standing_and_is_unknown_without_the_torso():
    assert trunk_lean_deg(_result(BODY_LANDMARK_NAMES)) == pytest.approx(0.0, abs=1e-6)
    lying = {n: (x, -0.05, -y) for n, (x, y, z) in STANDING.items()}      # the body along the depth axis
    assert trunk_lean_deg(_result(BODY_LANDMARK_NAMES, lying)) == pytest.approx(90.0, abs=1e-6)
    assert trunk_lean_deg(_result(set(BODY_LANDMARK_NAMES) - {"right_shoulder"})) is None
    # the fit's gravity, when it had one: a body upright in the camera's axes, seen by a camera tilted 30 degrees
    # down, leans 30 degrees from the true vertical
    down = [0.0, math.cos(math.radians(30)), math.sin(math.radians(30))]
    assert trunk_lean_deg(_result(BODY_LANDMARK_NAMES, down=down)) == pytest.approx(30.0, abs=1e-6)


def test_the_side_view_fills_its_height_and_shows_the_camera():
    h, w = 720, 560
    for absolute in (False, True):
        joints = {n: np.array(p) + (np.array([0.0, 0.0, 3.0]) if absolute else 0.0) for n, p in STANDING.items()}
        if not absolute:
            joints = {n: p - np.array([0.0, 0.88, 0.0]) for n, p in joints.items()}
        frame = SideFrame.for_clip([joints], absolute, 0.88 + 0.08 if absolute else 0.0)
        img = render_side(joints, frame, (w, h))
        bones = np.zeros(img.shape[:2], bool)
        for colour in (draw.LEFT, draw.RIGHT, draw.CENTRE):
            bones |= np.abs(img.astype(int) - np.array(colour)).sum(axis=2) < 60
        drawn = np.nonzero(bones)[0]
        usable = h - (TOP_PX + FLOOR_PX) * h / 720
        assert drawn.max() - drawn.min() > 0.75 * usable, absolute            # shoulders to ankles: most of it
        floor_rows = np.nonzero((img[:, w // 2] == (180, 170, 150)).all(axis=1))[0]
        assert floor_rows.min() > 0.85 * h                                      # a thin floor strip, no panel
        grey = (np.abs(img[:, :70].astype(int) - 200).sum(axis=2) < 30).sum()
        assert grey > 40, absolute                                              # the camera marker at the left


def test_history_stores_null_for_what_the_frame_did_not_see(tmp_path):
    r = FitResult(0, 0.0, True, joint_angles_deg={"theta_el_l": 90.0, "theta_kn_l": 5.0, "theta_hd": 0.0},
                  variables={"theta_bd": 2.0, "phi_bd": 0.0, "psi_bd": 0.0},
                  measured=Measured.from_landmarks(set(BODY_LANDMARK_NAMES) - {"left_wrist"}))
    with AngleHistory(tmp_path / "h.sqlite3", FallsConfig()) as hist:
        hist.add(r, wall=1000.0)
        [row] = list(hist.rows())
    value = dict(zip(ANGLE_COLUMNS, row[4:], strict=True))
    assert value["theta_el_l"] is None and value["theta_hd"] is None
    assert value["theta_kn_l"] == 5.0 and value["theta_bd"] == 2.0


def test_writing_webm_leaves_no_opencv_note_on_stderr(tmp_path, capfd):
    out = tmp_path / "x.webm"
    with VideoOut(out, 10.0, (64, 48)) as v:
        for i in range(5):
            v.write(np.full((48, 64, 3), 40 * i, np.uint8))
    err = capfd.readouterr().err
    assert "FFMPEG" not in err and "OpenCV" not in err, err
    cap = cv2.VideoCapture(str(out))
    assert cap.read()[0] and int(cap.get(cv2.CAP_PROP_FRAME_COUNT) or 5) == 5
    cap.release()


def test_the_overlay_says_which_evidence_the_fit_used():
    """Issue 38 item 5: `posed render` names what the 3D came from (the fit result's `evidence`), and says
    nothing when the fit did not say (a fit file written before the field existed)."""
    from posed.viz.names import evidence_text

    assert evidence_text(("landmarks", "world")) == "3D from: 2D landmarks + BlazePose 3D"
    assert evidence_text(["landmarks", "depth"]) == "3D from: 2D landmarks + depth camera"
    assert evidence_text(()) == ""
    # the lens is named only when it was assumed (a source without intrinsics: relative depth, no metres)
    assert evidence_text(("landmarks", "world"), "assumed") == "3D from: 2D landmarks + BlazePose 3D, assumed lens"
    assert evidence_text(("landmarks",), "given") == "3D from: 2D landmarks"
    seen = set(BODY_LANDMARK_NAMES)
    drawn = {}
    for ev in ((), ("landmarks", "world"), ("landmarks", "depth")):
        r = _result(seen)
        if ev:
            r.extra["evidence"] = list(ev)
        renderer = ClipRenderer((640, 480), K, [r])
        drawn[ev] = renderer.frame(None, FrameInput(0, 0.0, None, r))[:, :640]
    # the evidence line sits under the angle table: the three frames differ exactly there
    plain, world, depth = drawn.values()
    rows = lambda a, b: np.flatnonzero(np.any(a != b, axis=(1, 2)))   # noqa: E731
    assert rows(plain, world).size and rows(world, depth).size
    assert rows(plain, world).max() < 240 and rows(world, depth).min() == rows(plain, world).min()
