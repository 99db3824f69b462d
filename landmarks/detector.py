"""BlazePose person detector: tensor decoding, weighted NMS and letterbox removal (tech-notes d.2–d.5).

The detector's raw outputs per anchor are 12 regressors (box x, y, w, h, then 4 keypoints x, y; pixels of the
224×224 input relative to the anchor centre) and one score logit. Decoding follows MediaPipe's
``TensorsToDetectionsCalculator`` with the pose options (scale 224, ``reverse_output_order`` so x comes
first, sigmoid score with logits clipped to ±100, keep score ≥ ``min_score``); ``NonMaxSuppressionCalculator``
in WEIGHTED mode merges each cluster of boxes with IoU > 0.3 into the score-weighted mean; the letterbox is
then removed so every coordinate is normalized to the original frame (x / width, y / height).

Keypoints: 0 mid-hip centre, 1 full-body size/rotation point, 2 mid-shoulder centre, 3 upper-body point.
The box is the face box.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from posed.landmarks.anchors import INPUT_SIZE, NUM_ANCHORS, ssd_anchor_centres

NUM_COORDS = 12
NUM_KEYPOINTS = 4
SCORE_CLIP = 100.0
NMS_IOU = 0.3


@dataclass(frozen=True, eq=False)
class Detection:
    """One person: ``score`` in [0, 1]; ``box`` (4,) xmin, ymin, xmax, ymax and ``keypoints`` (4, 2) x, y,
    normalized to the frame the detector saw (or to the letterboxed input before :func:`remove_letterbox`)."""

    score: float
    box: np.ndarray
    keypoints: np.ndarray

    def keypoints_px(self, width: int, height: int) -> np.ndarray:
        """Keypoints in image pixels, (4, 2)."""
        return self.keypoints * np.array([width, height], dtype=np.float64)


def stable_sigmoid(x: np.ndarray) -> np.ndarray:
    """Logistic function without overflow for large |x| (float64)."""
    x = np.asarray(x, dtype=np.float64)
    out = np.empty_like(x)
    pos = x >= 0
    out[pos] = 1.0 / (1.0 + np.exp(-x[pos]))
    e = np.exp(x[~pos])
    out[~pos] = e / (1.0 + e)
    return out


def decode_raw(raw_boxes: np.ndarray, raw_scores: np.ndarray, anchors: np.ndarray,
               min_score: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Decode the detector tensors; returns ``scores (N,), boxes (N, 4), keypoints (N, 4, 2)`` of the anchors
    scoring at least ``min_score``, normalized to the 224×224 input.

    raw_boxes: (2254, 12) or (1, 2254, 12); raw_scores: (2254,), (2254, 1) or (1, 2254, 1) logits.
    """
    boxes = np.asarray(raw_boxes, dtype=np.float64).reshape(-1, NUM_COORDS)
    logits = np.asarray(raw_scores, dtype=np.float64).reshape(-1)
    if boxes.shape[0] != anchors.shape[0] or logits.shape[0] != anchors.shape[0]:
        raise ValueError(f"detector output has {boxes.shape[0]} boxes and {logits.shape[0]} scores, expected "
                         f"{anchors.shape[0]} (the SSD anchors of pose_detection)")
    scores = stable_sigmoid(np.clip(logits, -SCORE_CLIP, SCORE_CLIP))
    keep = scores >= min_score
    if not keep.any():
        return np.zeros(0), np.zeros((0, 4)), np.zeros((0, NUM_KEYPOINTS, 2))
    r = boxes[keep] / INPUT_SIZE
    a = anchors[keep]
    cx = r[:, 0] + a[:, 0]
    cy = r[:, 1] + a[:, 1]
    w = r[:, 2]
    h = r[:, 3]
    out_boxes = np.stack([cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2], axis=1)
    kps = r[:, 4:].reshape(-1, NUM_KEYPOINTS, 2) + a[:, None, :]
    valid = (w >= 0) & (h >= 0) & np.isfinite(out_boxes).all(axis=1) & np.isfinite(kps).all(axis=(1, 2))
    return scores[keep][valid], out_boxes[valid], kps[valid]


def iou(box: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """Intersection over union of one box (4,) with many (N, 4), corners xmin, ymin, xmax, ymax."""
    ix = np.minimum(box[2], boxes[:, 2]) - np.maximum(box[0], boxes[:, 0])
    iy = np.minimum(box[3], boxes[:, 3]) - np.maximum(box[1], boxes[:, 1])
    inter = np.where((ix > 0) & (iy > 0), ix * iy, 0.0)
    area = (box[2] - box[0]) * (box[3] - box[1])
    areas = (boxes[:, 2] - boxes[:, 0]) * (boxes[:, 3] - boxes[:, 1])
    union = area + areas - inter
    return np.divide(inter, union, out=np.zeros_like(inter), where=union > 0)


def weighted_nms(scores: np.ndarray, boxes: np.ndarray, keypoints: np.ndarray,
                 iou_threshold: float = NMS_IOU) -> list[Detection]:
    """MediaPipe's WEIGHTED non-maximum suppression, best first.

    Take the best remaining detection, gather every remaining one whose IoU with it is > ``iou_threshold``
    (itself included), output the score-weighted mean of their boxes and keypoints with the best score,
    drop the cluster, repeat.
    """
    order = np.argsort(-scores, kind="stable")
    remaining = order
    out: list[Detection] = []
    while remaining.size:
        best = remaining[0]
        overlap = iou(boxes[best], boxes[remaining])
        cluster = remaining[overlap > iou_threshold]
        rest = remaining[overlap <= iou_threshold]
        if cluster.size == 0:
            # A zero-area best box overlaps nothing, not even itself: MediaPipe emits it as is and stops.
            out.append(Detection(float(scores[best]), boxes[best].copy(), keypoints[best].copy()))
            break
        w = scores[cluster]
        total = w.sum()
        box = (boxes[cluster] * w[:, None]).sum(axis=0) / total
        kps = (keypoints[cluster] * w[:, None, None]).sum(axis=0) / total
        out.append(Detection(float(scores[best]), box, kps))
        remaining = rest
    return out


def remove_letterbox(det: Detection, padding: tuple[float, float, float, float]) -> Detection:
    """Map a detection from the letterboxed square to the frame (``DetectionLetterboxRemoval``)."""
    left, top, right, bottom = padding
    sx = 1.0 - left - right
    sy = 1.0 - top - bottom
    box = (det.box - np.array([left, top, left, top])) / np.array([sx, sy, sx, sy])
    kps = (det.keypoints - np.array([left, top])) / np.array([sx, sy])
    return Detection(det.score, box, kps)


class DetectorDecoder:
    """Anchors + decoding + NMS + letterbox removal for one detector model (stateless apart from anchors)."""

    def __init__(self, min_score: float = 0.5, iou_threshold: float = NMS_IOU) -> None:
        self.min_score = min_score
        self.iou_threshold = iou_threshold
        self.anchors = ssd_anchor_centres()
        assert self.anchors.shape == (NUM_ANCHORS, 2)

    def __call__(self, raw_boxes: np.ndarray, raw_scores: np.ndarray,
                 padding: tuple[float, float, float, float]) -> list[Detection]:
        """Detections normalized to the frame, best first."""
        scores, boxes, kps = decode_raw(raw_boxes, raw_scores, self.anchors, self.min_score)
        if scores.size == 0:
            return []
        return [remove_letterbox(d, padding) for d in weighted_nms(scores, boxes, kps, self.iou_threshold)]
