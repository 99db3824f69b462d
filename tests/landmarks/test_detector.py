import warnings

import numpy as np
import pytest

from posed.landmarks.anchors import ssd_anchor_centres
from posed.landmarks.detector import (
    Detection,
    DetectorDecoder,
    decode_raw,
    iou,
    remove_letterbox,
    stable_sigmoid,
    weighted_nms,
)


def test_stable_sigmoid_has_no_overflow_and_matches_the_definition():
    x = np.array([-1000.0, -100.0, -1.0, 0.0, 2.0, 100.0, 1000.0])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        s = stable_sigmoid(x)
    mid = np.array([-1.0, 0.0, 2.0])
    assert np.allclose(s[2:5], 1 / (1 + np.exp(-mid)))
    assert s[0] == 0.0 and s[-1] == 1.0 and 0 < s[1] < 1e-40


def test_decode_raw_box_and_keypoints_relative_to_anchor():
    anchors = ssd_anchor_centres()
    raw = np.zeros((2254, 12))
    logits = np.full(2254, -10.0)
    i = 100
    raw[i] = [22.4, -11.2, 44.8, 67.2, 0, 0, 2.24, 2.24, -2.24, 0, 0, 22.4]
    logits[i] = 3.0
    scores, boxes, kps = decode_raw(raw, logits, anchors, 0.5)
    ax, ay = anchors[i]
    assert scores.shape == (1,) and np.isclose(scores[0], 1 / (1 + np.exp(-3.0)))
    cx, cy, w, h = ax + 0.1, ay - 0.05, 0.2, 0.3
    assert np.allclose(boxes[0], [cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2])
    assert np.allclose(kps[0], [[ax, ay], [ax + 0.01, ay + 0.01], [ax - 0.01, ay], [ax, ay + 0.1]])


def test_decode_raw_keeps_score_at_threshold_and_drops_negative_sizes():
    anchors = ssd_anchor_centres()
    raw = np.zeros((1, 2254, 12))
    logits = np.full((1, 2254, 1), -50.0)
    logits[0, 5, 0] = 0.0        # score exactly 0.5: kept (>=)
    logits[0, 6, 0] = 500.0      # clipped to 100 -> score 1
    raw[0, 6, 2] = -1.0          # negative width: dropped
    logits[0, 7, 0] = 1.0
    scores, boxes, _ = decode_raw(raw, logits, anchors, 0.5)
    assert scores.tolist() == pytest.approx([0.5, 1 / (1 + np.exp(-1.0))])


def test_decode_raw_rejects_wrong_anchor_count():
    with pytest.raises(ValueError, match="2254"):
        decode_raw(np.zeros((100, 12)), np.zeros(100), ssd_anchor_centres(), 0.5)


def test_iou_basic_cases():
    a = np.array([0.0, 0.0, 2.0, 2.0])
    boxes = np.array([[0, 0, 2, 2], [1, 1, 3, 3], [2, 2, 3, 3], [5, 5, 5, 5.0]])
    assert np.allclose(iou(a, boxes), [1.0, 1 / 7, 0.0, 0.0])


def _reference_weighted_nms(scores, boxes, kps, thr):
    """Plain re-statement of MediaPipe's WEIGHTED NMS, one detection at a time."""
    remaining = sorted(range(len(scores)), key=lambda i: -scores[i])
    out = []
    while remaining:
        best = remaining[0]
        cluster = [i for i in remaining if iou(boxes[best], boxes[i:i + 1])[0] > thr]
        remaining = [i for i in remaining if i not in cluster]
        w = np.array([scores[i] for i in cluster])
        out.append((scores[best], (boxes[cluster] * w[:, None]).sum(0) / w.sum(),
                    (kps[cluster] * w[:, None, None]).sum(0) / w.sum()))
    return out


def test_weighted_nms_matches_a_plain_reference():
    rng = np.random.default_rng(7)
    centres = rng.uniform(0.2, 0.8, size=(3, 2))
    boxes, kps, scores = [], [], []
    for c in centres:  # three people, each with a cloud of overlapping boxes
        for _ in range(6):
            cx, cy = c + rng.normal(0, 0.01, 2)
            w, h = rng.uniform(0.1, 0.12, 2)
            boxes.append([cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2])
            kps.append(np.array([cx, cy]) + rng.normal(0, 0.01, (4, 2)))
            scores.append(rng.uniform(0.5, 1.0))
    boxes, kps, scores = np.array(boxes), np.array(kps), np.array(scores)
    got = weighted_nms(scores, boxes, kps, 0.3)
    want = _reference_weighted_nms(scores, boxes, kps, 0.3)
    assert len(got) == len(want) >= 3
    for d, (s, b, k) in zip(got, want, strict=True):
        assert d.score == pytest.approx(s)
        assert np.allclose(d.box, b) and np.allclose(d.keypoints, k)
    assert [d.score for d in got] == sorted((d.score for d in got), reverse=True)


def test_weighted_nms_averages_by_score():
    boxes = np.array([[0.0, 0.0, 1.0, 1.0], [0.1, 0.0, 1.1, 1.0]])
    kps = np.zeros((2, 4, 2))
    kps[1] += 1.0
    got = weighted_nms(np.array([0.9, 0.6]), boxes, kps, 0.3)
    assert len(got) == 1 and got[0].score == 0.9
    assert np.allclose(got[0].box, [0.04, 0.0, 1.04, 1.0])
    assert np.allclose(got[0].keypoints, 0.4)


def test_remove_letterbox_maps_back_to_the_frame():
    det = Detection(0.9, np.array([0.25, 0.25, 0.75, 0.75]), np.array([[0.5, 0.2]] * 4))
    out = remove_letterbox(det, (0.0, 0.2, 0.0, 0.2))  # wide frame: bands top and bottom
    assert np.allclose(out.box, [0.25, 0.05 / 0.6, 0.75, 0.55 / 0.6])
    assert np.allclose(out.keypoints[0], [0.5, 0.0])


def test_decoder_returns_nothing_when_nothing_scores():
    decode = DetectorDecoder(0.5)
    assert decode(np.zeros((2254, 12)), np.full(2254, -5.0), (0, 0, 0, 0)) == []
