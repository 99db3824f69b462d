"""Conformance of the landmark stage (onnxruntime on the converted models) with MediaPipe's own outputs, on the
real test data. Measured numbers are attached to the test report with ``record_property``."""

from __future__ import annotations

import json
import re
from pathlib import Path

import cv2
import numpy as np
import pytest

from posed.bench import conformance
from posed.landmarks.config import LandmarkConfig
from posed.landmarks.pipeline import PoseLandmarker, rotate_image, rotate_points, unrotate_points
from posed.landmarks.recording import LandmarkFrame

BODY = list(conformance.BODY)
COCO_TO_MP = list(conformance.COCO_TO_MP)
# MediaPipe's tolerance for normalized pose landmarks, each of x and y: _LANDMARKS_MARGIN = 0.03 in the Tasks API
# test (mediapipe/tasks/python/test/vision/pose_landmarker_test.py), used here against the Tasks expectation
# of pose.jpg and the iOS sample's "full" output of the sitting image (bench/conformance.py: 0.03 x width).
LANDMARKS_MARGIN = 0.03


def _pbtxt_blocks(path: Path, block: str) -> list[dict]:
    text = path.read_text()
    return [{k: float(v) for k, v in re.findall(r"(\w+):\s*([-\d.eE]+)", b)}
            for b in re.findall(block + r"\s*\{([^{}]*)\}", text)]


@pytest.fixture(scope="module")
def landmarker(models_dir) -> PoseLandmarker:
    lm = PoseLandmarker(LandmarkConfig(), models_dir=models_dir)
    lm.warmup()
    return lm


@pytest.fixture(scope="module")
def pose_jpg(shared_data):
    d = shared_data / "reference" / "mediapipe_pose_jpg"
    image = cv2.imread(str(d / "pose.jpg"))
    expected = json.loads((d / "pose_test_py_expected.json").read_text())
    return image, expected, d


@pytest.fixture(scope="module")
def squat_frames(shared_data):
    return conformance.squat_video(shared_data)


def _fresh(landmarker):
    landmarker.reset()
    return landmarker


# -- pose.jpg: MediaPipe's own test image ------------------------------------------------------------------------

def test_detection_and_roi_match_mediapipe_on_pose_jpg(landmarker, pose_jpg, record_property):
    image, _, d = pose_jpg
    h, w = image.shape[:2]
    det, rotation = landmarker.detect(image)
    assert det is not None and rotation == 0
    want = _pbtxt_blocks(d / "pose_expected_detection.pbtxt", "relative_bounding_box")[0]
    want_kps = _pbtxt_blocks(d / "pose_expected_detection.pbtxt", "relative_keypoints")
    assert det.score == pytest.approx(0.9843089, abs=0.01)
    assert det.box[:2] == pytest.approx([want["xmin"], want["ymin"]], abs=0.005)
    assert (det.box[2:] - det.box[:2]) == pytest.approx([want["width"], want["height"]], abs=0.005)
    assert det.keypoints == pytest.approx(np.array([[k["x"], k["y"]] for k in want_kps]), abs=0.005)

    result = _fresh(landmarker).process_full(image, 0.0, 0)
    rect = {k: float(v) for k, v in re.findall(r"(\w+):\s*([-\d.eE]+)",
                                                  (d / "pose_expected_expanded_rect.pbtxt").read_text())}
    roi = result.roi
    assert roi.cx / w == pytest.approx(rect["x_center"], abs=0.002)
    assert roi.cy / h == pytest.approx(rect["y_center"], abs=0.002)
    assert roi.size / h == pytest.approx(rect["height"], rel=0.01)
    assert roi.size / w == pytest.approx(rect["width"], rel=0.01)
    assert roi.rotation == pytest.approx(rect["rotation"], abs=0.01)
    record_property("roi_size_rel_diff", roi.size / (rect["height"] * h) - 1)


def test_pose_jpg_landmarks_within_mediapipes_tolerances(landmarker, pose_jpg, record_property):
    image, expected, d = pose_jpg
    h, w = image.shape[:2]
    result = _fresh(landmarker).process_full(image, 0.0, 0)
    lms = result.frame.landmarks
    assert lms is not None and lms.shape == (33, 5)
    err = np.linalg.norm(lms[:, :2] - np.array(expected["EXPECTED_POSE_LANDMARKS"]), axis=1)
    record_property("pose_jpg_max_px", float(err.max()))
    assert err.max() < expected["DIFF_THRESHOLD"]  # 15 px, all 33 landmarks (MediaPipe 0.10.21 here: 8.4)

    tasks = np.array([[b["x"], b["y"]] for b in _pbtxt_blocks(d / "pose_landmarks.pbtxt", "landmark")])
    norm_err = np.abs(lms[:, :2] / [w, h] - tasks)
    record_property("pose_jpg_body_max_norm", float(norm_err[BODY].max()))
    assert norm_err[BODY].max() <= LANDMARKS_MARGIN

    world = result.world_landmarks
    assert world.shape == (33, 5)
    world_err = np.abs(world[:, :3] - np.array(expected["EXPECTED_POSE_WORLD_LANDMARKS"]))
    record_property("pose_jpg_world_max_m", float(world_err.max()))
    assert world_err.max() < expected["WORLD_DIFF_THRESHOLD"]  # 0.2 m
    assert ((lms[:, 3:] >= 0) & (lms[:, 3:] <= 1)).all()
    assert lms[BODY, 3].min() > 0.5  # the whole body is in view


# -- video: tracking -----------------------------------------------------------------------------------------------

def test_squat_video_tracking_matches_the_reference(landmarker, squat_frames, pose_jpg, record_property):
    """The reference was produced with timestamps 33.3 ms apart whatever the video's rate (tfjs-models'
    pose test, following MediaPipe's solution_base.py), so the frames are fed at a simulated 30 fps."""
    frames, expected = squat_frames
    assert len(frames) == len(expected) == 65 and frames[0].shape == (1280, 720, 3)
    lm = _fresh(landmarker)
    errors, detector_runs = [], 0
    for seq, image in enumerate(frames):
        result = lm.process_full(image, seq / 30.0, seq)
        detector_runs += result.detector_ran
        assert result.frame.landmarks is not None, f"lost the person at frame {seq}"
        errors.append(np.linalg.norm(result.frame.landmarks[BODY, :2] - expected[seq][BODY, :2], axis=1))
    errors = np.array(errors)
    p99 = float(np.percentile(errors, 99))
    record_property("squat_mean_px", float(errors.mean()))
    record_property("squat_p99_px", p99)
    record_property("squat_max_px", float(errors.max()))
    assert detector_runs == 1  # tracked from the first detection to the end
    # 15 px is MediaPipe's own per-landmark tolerance for its pose tests (DIFF_THRESHOLD of pose_test.py, static
    # and video mode; the same bound as on pose.jpg above). It bounds the 99th percentile of the 780 errors (at
    # most 7 above it), not the maximum: in tracking mode each frame's landmarks place the next frame's crop,
    # so a rounding difference (another CPU's float32 kernels) moves the single worst landmark by ~2 px
    # (14.99-16.9 px measured across onnxruntime settings and +-1 LSB image noise) while the percentile
    # (12.8-13.1 px) and the mean stay put. 5 px mean: MediaPipe 0.10.21 itself is 4.1 px from this reference
    # (docs/landmarks.md); a mean over 780 errors is not moved by one landmark.
    assert errors.mean() <= 5.0 and p99 <= pose_jpg[1]["DIFF_THRESHOLD"]


def test_reset_makes_runs_repeatable(landmarker, squat_frames):
    frames, _ = squat_frames
    runs = []
    for _ in range(2):
        landmarker.reset()
        runs.append([landmarker.process(image, seq / 30.0, seq) for seq, image in enumerate(frames[:6])])
    assert runs[0] == runs[1]


def test_losing_the_person_resets_and_redetects(landmarker, squat_frames):
    frames, _ = squat_frames
    lm = _fresh(landmarker)
    for seq in range(3):
        assert lm.process_full(frames[seq], seq / 30, seq).next_roi is not None
    empty = np.full_like(frames[0], 127)
    lost = lm.process_full(empty, 3 / 30, 3)
    assert lost.frame.landmarks is None and lost.next_roi is None and not lost.detector_ran
    assert lost.pose_flag is not None and lost.pose_flag < 0.5
    again = lm.process_full(empty, 4 / 30, 4)
    assert again.detector_ran and again.frame.landmarks is None and again.pose_flag is None
    back = lm.process_full(frames[5], 5 / 30, 5)
    assert back.detector_ran and back.frame.landmarks is not None


def test_static_mode_detects_every_frame_without_smoothing(models_dir, squat_frames):
    frames, _ = squat_frames
    lm = PoseLandmarker(LandmarkConfig(tracking=False), models_dir=models_dir)
    results = [lm.process_full(frames[seq], seq / 30, seq) for seq in (10, 10, 11)]
    assert all(r.detector_ran for r in results)
    assert np.array_equal(results[0].frame.landmarks, results[1].frame.landmarks)


# -- other images --------------------------------------------------------------------------------------------------

def test_sitting_image_matches_the_full_model_reference(landmarker, shared_data, record_property):
    ref = conformance.sitting(shared_data)
    image, expected = ref.image, ref.expected
    h, w = image.shape[:2]
    lms = _fresh(landmarker).process(image, 0.0, 0).landmarks
    assert lms is not None
    norm_err = np.abs((lms[BODY, :2] - expected[BODY]) / [w, h])
    record_property("sitting_body_max_norm", float(norm_err.max()))
    assert norm_err.max() <= LANDMARKS_MARGIN  # measured 0.016


def test_coco_785_pck_against_human_labels(landmarker, shared_data, record_property):
    ref = conformance.coco_785(shared_data)
    lms = _fresh(landmarker).process(ref.image, 0.0, 0).landmarks
    assert lms is not None
    err = np.linalg.norm(lms[COCO_TO_MP, :2] - ref.expected[COCO_TO_MP], axis=1)
    pck = float(np.mean(err <= ref.tolerance_px))  # 0.2 x torso
    record_property("coco785_pck02_torso", pck)
    record_property("coco785_mean_px", float(err.mean()))
    # At least 16 of the 17 keypoints within PCK@0.2 (the 0.2 x torso radius of the PCK metric): MediaPipe
    # 0.10.21's own score on the same pixels (docs/landmarks.md); 15 of 17 (0.88) fails. The score counts
    # keypoints, so only one lying at the radius could flip with rounding: the nearest are 6.9 px inside
    # (14.3 px) and 3.6 px outside (the left ankle, 24.8 px, radius 21.2 px), float32 noise moves a
    # single-image landmark by ~1e-3 px.
    assert pck >= 0.9


# -- rotated copies and the rotation fallback ---------------------------------------------------------------------

def test_point_rotation_helpers_match_cv2_rotate():
    img = np.zeros((5, 8, 3), np.uint8)
    img[1, 6] = 255  # x=6, y=1
    for deg in (90, -90, 180):
        rot = rotate_image(img, deg)
        ys, xs = np.nonzero(rot[..., 0])
        assert rotate_points(np.array([[6.0, 1.0]]), deg, 8, 5).tolist() == [[xs[0], ys[0]]]
        assert unrotate_points(np.array([[xs[0], ys[0]]], float), deg, 8, 5).tolist() == [[6.0, 1.0]]


@pytest.mark.parametrize("degrees", [90, -90, 180])
@pytest.mark.parametrize("which", ["pose", "sitting", "coco"])
def test_rotated_copies_are_still_found(landmarker, shared_data, which, degrees, record_property):
    ref = {"pose": conformance.pose_jpg, "sitting": conformance.sitting, "coco": conformance.coco_785}[which](
        shared_data)
    image, expected, idx, tol = ref.image, ref.expected, list(ref.indices), ref.tolerance_px
    h, w = image.shape[:2]
    result = _fresh(landmarker).process_full(rotate_image(image, degrees), 0.0, 0)
    assert result.frame.landmarks is not None, f"{which} rotated {degrees} deg: nobody found"
    err = np.linalg.norm(result.frame.landmarks[idx, :2] - rotate_points(expected[idx], degrees, w, h), axis=1)
    record_property(f"{which}_rot{degrees}_max_px", float(err.max()))
    record_property(f"{which}_rot{degrees}_within_tol", float(np.mean(err <= tol)))
    if which == "pose":
        assert err.max() < tol
    else:
        # MediaPipe itself does not hold every landmark within these tolerances on rotated copies (sitting
        # turned 90 deg: 11 of 12, docs/landmarks.md), so the share within is asked, not the maximum. A count
        # moves by whole landmarks: at least three quarters (9 of 12, 13 of 17) stays two landmarks below
        # the worst share of posed and MediaPipe (11 of 12), so no landmark near the radius decides it, while
        # a wrong rotation mapping puts almost none within. The mean within half the tolerance: measured
        # 7.4-8.9 px of 14.4 (sitting), 6.6-7.5 px of 10.6 (COCO 785), a mean of 12 or 17 errors.
        assert np.mean(err <= tol) >= 0.75 and err.mean() <= tol / 2


@pytest.mark.parametrize("angle", [90, 180])
def test_rotation_fallback_finds_a_small_person_the_upright_detector_misses(models_dir, pose_jpg, angle):
    """pose.jpg at half size in a 1280x720 frame, lying (90) or upside down (180): the detector does not
    find the person in the upright frame, the +-90 deg retry does, and the landmarks are right."""
    image, expected, _ = pose_jpg
    h, w = image.shape[:2]
    m = cv2.getRotationMatrix2D((w / 2, h / 2), angle, 0.5)
    m[:, 2] += [(1280 - w) / 2, (720 - h) / 2]
    frame = cv2.warpAffine(image, m, (1280, 720), borderValue=(128, 128, 128))
    want = np.array(expected["EXPECTED_POSE_LANDMARKS"], float) @ m[:, :2].T + m[:, 2]

    plain = PoseLandmarker(LandmarkConfig(rotate_on_miss=False), models_dir=models_dir)
    assert plain.process(frame, 0.0, 0).landmarks is None

    fallback = PoseLandmarker(LandmarkConfig(rotate_on_miss=True), models_dir=models_dir)
    result = fallback.process_full(frame, 0.0, 0)
    assert result.frame.landmarks is not None and result.rotation in (90, -90)
    err = np.linalg.norm(result.frame.landmarks[:, :2] - want, axis=1)
    assert err.max() < expected["DIFF_THRESHOLD"] * 0.5  # MediaPipe's 15 px at the half scale (measured 5.9-6.0)
    x0, y0, x1, y1 = result.detection.box * [1280, 720, 1280, 720]  # the face box, mapped back to the frame
    assert x0 < want[0, 0] < x1 and y0 < want[0, 1] < y1


# -- API edges -----------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("bad, words", [
    (np.zeros((10, 10), np.uint8), "shape (10, 10)"),
    (np.zeros((10, 10, 4), np.uint8), "shape (10, 10, 4)"),
    (np.zeros((10, 10, 3), np.float32), "dtype float32"),
    (np.zeros((0, 10, 3), np.uint8), "shape (0, 10, 3)"),
    ([[1, 2, 3]], "got list"),
])
def test_wrong_images_are_refused_clearly(landmarker, bad, words):
    with pytest.raises(ValueError) as err:
        landmarker.process(bad, 0.0, 0)
    assert "expected" in str(err.value) and words in str(err.value)


def test_result_extras_do_not_change_the_frame_json(landmarker, pose_jpg):
    image, _, _ = pose_jpg
    result = _fresh(landmarker).process_full(image, 1.5, 7)
    assert landmarker.last_result is result
    obj = result.frame.to_json()
    # the ROI, timings and aux landmarks stay out; the world landmarks are the frame's (interfaces.md section 1)
    assert set(obj) == {"seq", "t", "landmarks", "world"} and obj["seq"] == 7 and obj["t"] == 1.5
    assert result.world_landmarks is result.frame.world
    assert LandmarkFrame.from_json(json.loads(json.dumps(obj))) == result.frame
    assert result.aux_landmarks.shape == (2, 5) and result.next_roi is not None
    assert set(result.timings_ms) >= {"detector", "crop", "landmark_model", "decode", "smoothing"}
