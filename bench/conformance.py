"""The real references of the landmark stage in the shared test data (``$POSED_SHARED_DATA``, see its README).

Each image reference carries the BGR image, the expected landmarks in pixels (33 × 2, NaN where there is no
reference), which landmarks are compared and the tolerance in pixels. Used by ``posed bench peer`` and the
conformance tests.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from posed.daemon.preflight import SQUAT_VIDEO

BODY = (11, 12, 13, 14, 15, 16, 23, 24, 25, 26, 27, 28)  # shoulders, elbows, wrists, hips, knees, ankles
COCO_TO_MP = (0, 2, 5, 7, 8, 11, 12, 13, 14, 15, 16, 23, 24, 25, 26, 27, 28)  # COCO's 17 keypoints, in order


@dataclass(frozen=True)
class ImageReference:
    name: str
    image: np.ndarray  # BGR, H × W × 3
    expected: np.ndarray  # (33, 2) pixels; NaN = no reference for that landmark
    indices: tuple[int, ...]  # the landmarks compared
    tolerance_px: float
    source: str  # what the expectation is


def _read(path: Path) -> np.ndarray:
    image = cv2.imread(str(path))
    if image is None:
        raise FileNotFoundError(f"{path} is missing or unreadable; the shared test data must be at "
                                "../shared/data or $POSED_SHARED_DATA")
    return image


def pose_jpg(root: Path) -> ImageReference:
    """MediaPipe's pose.jpg: all 33 landmarks, MediaPipe's own 15 px tolerance (``pose_test.py``)."""
    d = root / "reference" / "mediapipe_pose_jpg"
    expected = json.loads((d / "pose_test_py_expected.json").read_text())
    return ImageReference("pose.jpg", _read(d / "pose.jpg"), np.array(expected["EXPECTED_POSE_LANDMARKS"], float),
                          tuple(range(33)), float(expected["DIFF_THRESHOLD"]), "MediaPipe pose_test.py")


def sitting(root: Path) -> ImageReference:
    """The iOS sample's sitting person: the 12 body landmarks of the "full" model, 0.03 of the width."""
    d = root / "reference" / "mediapipe_samples_ios_sitting"
    image = _read(d / "test_image.jpg")
    h, w = image.shape[:2]
    full = np.array(json.loads((d / "expected_landmarks.json").read_text())["full"], float)[:, :2] * [w, h]
    return ImageReference("sitting", image, full, BODY, 0.03 * w, "MediaPipe iOS sample, full model")


def coco_785(root: Path) -> ImageReference:
    """COCO val2017 785: the 17 human-labelled keypoints; tolerance 0.2 × torso (PCK@0.2, left shoulder to
    right hip)."""
    d = root / "images" / "coco_cc_by"
    ann = json.loads((d / "coco_val2017_000000000785_keypoints.json").read_text())["annotations"][0]
    kps = np.array(ann["keypoints"], float).reshape(17, 3)
    expected = np.full((33, 2), np.nan)
    expected[list(COCO_TO_MP)] = kps[:, :2]
    torso = float(np.linalg.norm(kps[5, :2] - kps[12, :2]))
    return ImageReference("COCO 785", _read(d / "coco_val2017_000000000785.jpg"), expected, COCO_TO_MP,
                          0.2 * torso, "human labels")


def squat_video(root: Path) -> tuple[list[np.ndarray], np.ndarray]:
    """The 65 frames of tfjs-models' squat video (BGR) and the reference landmarks per frame (65, 33, ≥ 2)
    in pixels, made by MediaPipe's full model with frames stamped 1/30 s apart."""
    cap = cv2.VideoCapture(str(root / SQUAT_VIDEO))
    frames = []
    while True:
        ok, image = cap.read()
        if not ok:
            break
        frames.append(image)
    cap.release()
    if not frames:
        raise FileNotFoundError(f"{root / SQUAT_VIDEO} is missing or unreadable")
    expected = np.array(json.loads((root / SQUAT_VIDEO.with_name("pose_squats.full.json")).read_text()), float)
    return frames, expected
