"""MediaPipe Pose (BlazePose full) as MediaPipe runs it, on onnxruntime: :class:`PoseLandmarker`.

Per frame (tech-notes d.2–d.10):

1. ROI: the previous frame's (from its smoothed auxiliary landmarks) while tracking; otherwise run the
   detector on the letterboxed frame, take the best detection and build the ROI from keypoints 0 and 1.
   When the detector finds nobody and ``rotate_on_miss`` is on, the frame is rotated by +90° and then −90°
   and the detector tried again (a person lying on the floor); the detection is mapped back to the frame,
   whose ROI then carries the rotation, so the landmark model sees the person upright.
2. Crop the rotated ROI to 256×256 and run the landmark model.
3. Pose flag < ``min_tracking_confidence`` → no person this frame; the filters are reset and the next frame
   runs the detector.
4. Decode 39 landmarks (heatmap refinement), project to image pixels; world landmarks rotated by the ROI.
5. Smooth (one-euro, MediaPipe's parameters) with the frame time ``t``; the next ROI comes from the smoothed
   auxiliary landmarks 33 and 34.

``process`` returns the :class:`~landmarks.recording.LandmarkFrame`; ``last_result`` (a :class:`PoseResult`)
also carries the world landmarks, the ROI, the pose flag, the detection and per-step timings of that frame.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from posed.landmarks.config import LandmarkConfig
from posed.landmarks.crop import detector_input, landmark_input
from posed.landmarks.decode import AUX_END, AUX_START, NUM_BODY_LANDMARKS, decode_pose
from posed.landmarks.detector import Detection, DetectorDecoder
from posed.landmarks.models import default_models_dir, find_models, verify_models
from posed.landmarks.recording import LandmarkFrame
from posed.landmarks.roi import Roi, roi_from_alignment
from posed.landmarks.runtime import (
    DETECTOR_INPUT,
    LANDMARK_INPUT,
    DetectorRunner,
    LandmarkRunner,
    OnnxDetector,
    OnnxLandmarkModel,
    SessionSettings,
)
from posed.landmarks.smoothing import PoseSmoother

# Rotations (degrees, clockwise on screen) tried in turn when the detector finds nobody in the upright frame.
FALLBACK_ROTATIONS = (90, -90)


@dataclass(frozen=True, eq=False)
class PoseResult:
    """Everything found in one frame.

    frame: what ``process`` returns. world_landmarks: (33, 5) ``[x, y, z, visibility, presence]`` with x, y, z
    in metres, origin between the hips, axes of the image (x right, y down, z away from the camera), or None.
    roi: the region the landmark model looked at (image pixels) or None; next_roi: the region the next frame
    will use (None = the detector runs). pose_flag: the model's pose-presence probability (None if the model
    did not run). detection: the detector's best detection, normalized to the frame, when the detector ran
    and found someone; rotation: the rotation of the frame (degrees, 0 = upright) in which it was found.
    detector_ran: whether the detector ran. timings_ms: milliseconds per step (detector, crop, landmark_model,
    decode, smoothing).
    """

    frame: LandmarkFrame
    world_landmarks: np.ndarray | None = None
    aux_landmarks: np.ndarray | None = None
    roi: Roi | None = None
    next_roi: Roi | None = None
    pose_flag: float | None = None
    detection: Detection | None = None
    rotation: int = 0
    detector_ran: bool = False
    timings_ms: dict = field(default_factory=dict)


def check_image(image: object) -> np.ndarray:
    """The image as a C-contiguous H×W×3 uint8 array, or ValueError naming what was expected and got."""
    if not isinstance(image, np.ndarray):
        raise ValueError(f"expected an H×W×3 uint8 BGR numpy array, got {type(image).__name__}")
    if image.ndim != 3 or image.shape[2] != 3 or image.shape[0] < 1 or image.shape[1] < 1:
        raise ValueError(f"expected an H×W×3 uint8 BGR image, got shape {image.shape}")
    if image.dtype != np.uint8:
        raise ValueError(f"expected an H×W×3 uint8 BGR image, got dtype {image.dtype} (shape {image.shape})")
    return np.ascontiguousarray(image)


def rotate_image(image: np.ndarray, degrees: int) -> np.ndarray:
    """The image turned by ±90° or 180° (clockwise on screen for positive degrees)."""
    code = {90: cv2.ROTATE_90_CLOCKWISE, -90: cv2.ROTATE_90_COUNTERCLOCKWISE, 180: cv2.ROTATE_180}[degrees]
    return cv2.rotate(image, code)


def unrotate_points(points: np.ndarray, degrees: int, width: int, height: int) -> np.ndarray:
    """Pixel points (N, 2) of the image rotated by ``degrees`` → pixels of the original W×H image."""
    x, y = points[:, 0], points[:, 1]
    if degrees == 90:        # rotated (x', y') = (H − 1 − y, x)
        return np.stack([y, height - 1 - x], axis=1)
    if degrees == -90:       # rotated (x', y') = (y, W − 1 − x)
        return np.stack([width - 1 - y, x], axis=1)
    if degrees == 180:
        return np.stack([width - 1 - x, height - 1 - y], axis=1)
    raise ValueError(f"rotation must be 90, -90 or 180 degrees, got {degrees}")


def rotate_points(points: np.ndarray, degrees: int, width: int, height: int) -> np.ndarray:
    """Pixel points (N, 2) of the original W×H image → pixels of the image rotated by ``degrees``."""
    x, y = points[:, 0], points[:, 1]
    if degrees == 90:
        return np.stack([height - 1 - y, x], axis=1)
    if degrees == -90:
        return np.stack([y, width - 1 - x], axis=1)
    if degrees == 180:
        return np.stack([width - 1 - x, height - 1 - y], axis=1)
    raise ValueError(f"rotation must be 90, -90 or 180 degrees, got {degrees}")


def load_runners(config: LandmarkConfig, models_dir: Path | None) -> tuple[OnnxDetector, OnnxLandmarkModel]:
    """onnxruntime sessions for the converted models, checked against their manifest.

    Raises ``ModelMissingError`` when a file is not there and ``ModelCorruptError`` when one is damaged
    (both name the folder and ``posed models fetch``)."""
    folder = Path(models_dir) if models_dir is not None else default_models_dir(config.models_dir)
    paths = find_models(folder)
    verify_models(paths)
    settings = SessionSettings(threads=config.threads)
    return OnnxDetector(paths.detector_onnx, settings), OnnxLandmarkModel(paths.landmark_onnx, settings)


class PoseLandmarker:
    """BlazePose full, one person, tracking across calls (MediaPipe's video mode) unless ``config.tracking``
    is off (then every frame is detected and nothing is smoothed, MediaPipe's static-image mode).

    ``detector`` and ``landmark_model`` may be given to run other back ends on the same pipeline (the
    benchmark uses this to run LiteRT); by default the converted ONNX models in ``models_dir`` (or
    ``config.models_dir``) are loaded.
    """

    def __init__(self, config: LandmarkConfig | None = None, models_dir: Path | None = None, *,
                 detector: DetectorRunner | None = None, landmark_model: LandmarkRunner | None = None) -> None:
        self.config = config if config is not None else LandmarkConfig()
        if detector is None or landmark_model is None:
            onnx_detector, onnx_landmarks = load_runners(self.config, models_dir)
            detector = detector or onnx_detector
            landmark_model = landmark_model or onnx_landmarks
        self.detector = detector
        self.landmark_model = landmark_model
        self.decoder = DetectorDecoder(min_score=self.config.min_detection_confidence)
        self.smoother = PoseSmoother(smooth_landmarks=self.config.smoothing and self.config.tracking)
        self._roi: Roi | None = None
        self.last_result: PoseResult | None = None

    # -- public API ------------------------------------------------------------------------------------------

    def reset(self) -> None:
        """Forget the tracked person: the next frame runs the detector and the filters start again."""
        self._roi = None
        self.smoother.reset()
        self.last_result = None

    def warmup(self) -> None:
        """Run both models once so the first real frame does not pay for allocation and kernel selection."""
        self.detector(np.zeros((1, DETECTOR_INPUT, DETECTOR_INPUT, 3), np.float32))
        self.landmark_model(np.zeros((1, LANDMARK_INPUT, LANDMARK_INPUT, 3), np.float32))

    def process(self, image_bgr: np.ndarray, t: float, seq: int) -> LandmarkFrame:
        """Landmarks of the person in ``image_bgr`` (H×W×3 uint8 BGR) captured at ``t`` seconds."""
        return self.process_full(image_bgr, t, seq).frame

    def process_full(self, image_bgr: np.ndarray, t: float, seq: int) -> PoseResult:
        """Like :meth:`process`, returning the whole :class:`PoseResult` (also kept in ``last_result``)."""
        image = check_image(image_bgr)
        if not self.config.tracking:
            self._roi = None
            self.smoother.reset()
        result = self._process(image, float(t), int(seq))
        self.last_result = result
        return result

    def detect(self, image_bgr: np.ndarray) -> tuple[Detection | None, int]:
        """The best detection (normalized to the frame) and the rotation it was found in, or (None, 0)."""
        image = check_image(image_bgr)
        return self._detect(image)

    # -- steps -------------------------------------------------------------------------------------------------

    def _detect_upright(self, image: np.ndarray) -> Detection | None:
        tensor, padding = detector_input(image)
        out = self.detector(tensor)
        detections = self.decoder(out.boxes, out.scores, padding)
        return detections[0] if detections else None

    def _detect(self, image: np.ndarray) -> tuple[Detection | None, int]:
        det = self._detect_upright(image)
        if det is not None or not self.config.rotate_on_miss:
            return det, 0
        h, w = image.shape[:2]
        for degrees in FALLBACK_ROTATIONS:
            rotated = rotate_image(image, degrees)
            det = self._detect_upright(rotated)
            if det is None:
                continue
            rh, rw = rotated.shape[:2]
            scale = np.array([rw, rh], dtype=np.float64)
            kps = unrotate_points(det.keypoints * scale, degrees, w, h) / np.array([w, h], dtype=np.float64)
            x0, y0, x1, y1 = det.box * np.tile(scale, 2)
            corners = unrotate_points(np.array([[x0, y0], [x1, y1]]), degrees, w, h)
            box = np.concatenate([corners.min(axis=0), corners.max(axis=0)]) / np.array([w, h, w, h], float)
            return Detection(det.score, box, kps), degrees
        return None, 0

    def _process(self, image: np.ndarray, t: float, seq: int) -> PoseResult:
        h, w = image.shape[:2]
        timings: dict[str, float] = {}
        detection: Detection | None = None
        rotation = 0
        detector_ran = self._roi is None
        if self._roi is None:
            t0 = time.perf_counter()
            detection, rotation = self._detect(image)
            timings["detector"] = (time.perf_counter() - t0) * 1e3
            if detection is None:
                self.smoother.reset()
                return PoseResult(LandmarkFrame(seq, t, None), detector_ran=True, timings_ms=timings)
            kps = detection.keypoints_px(w, h)
            roi = roi_from_alignment(kps[0], kps[1])
        else:
            roi = self._roi
        return self.landmark_pass(image, roi, t, seq, detection=detection, rotation=rotation,
                                  detector_ran=detector_ran, timings=timings)

    def landmark_pass(self, image: np.ndarray, roi: Roi, t: float, seq: int, *, detection: Detection | None = None,
                      rotation: int = 0, detector_ran: bool = False, timings: dict | None = None) -> PoseResult:
        """One landmark-model pass on ``roi`` of ``image`` (checked H×W×3 uint8): crop, model, decode, smooth;
        the next frame's ROI is kept (tracking) or forgotten (pose flag below ``min_tracking_confidence``).
        :class:`~landmarks.people.MultiPoseLandmarker` runs one per person, each on its own landmarker."""
        timings = {} if timings is None else timings
        t0 = time.perf_counter()
        tensor = landmark_input(image, roi)
        t1 = time.perf_counter()
        out = self.landmark_model(tensor)
        t2 = time.perf_counter()
        timings["crop"] = (t1 - t0) * 1e3
        timings["landmark_model"] = (t2 - t1) * 1e3

        if not out.pose_flag >= self.config.min_tracking_confidence:
            self._roi = None
            self.smoother.reset()
            return PoseResult(LandmarkFrame(seq, t, None), roi=roi, pose_flag=out.pose_flag,
                              detection=detection, rotation=rotation, detector_ran=detector_ran,
                              timings_ms=timings)

        image_lms, world = decode_pose(out.landmarks, out.heatmap, out.world, roi)
        t3 = time.perf_counter()
        timings["decode"] = (t3 - t2) * 1e3

        body = image_lms[:NUM_BODY_LANDMARKS]
        aux = image_lms[AUX_START:AUX_END + 1]
        world_body = world[:NUM_BODY_LANDMARKS]
        if self.config.keep_sides:
            body, world_body, _ = self.smoother.sides.check(t, body, world_body)
        body_s, aux_s, world_s, world_vis = self.smoother.apply(t, body, aux, world_body)
        next_roi = roi_from_alignment(aux_s[0, :2], aux_s[1, :2])
        self._roi = next_roi
        timings["smoothing"] = (time.perf_counter() - t3) * 1e3

        world_out = np.empty((NUM_BODY_LANDMARKS, 5))
        world_out[:, :3] = world_s
        world_out[:, 3] = world_vis
        world_out[:, 4] = body[:, 4]
        frame = LandmarkFrame(seq, t, body_s, world=world_out)
        return PoseResult(frame, frame.world, aux_s, roi, next_roi, out.pose_flag, detection, rotation,
                          detector_ran, timings)
