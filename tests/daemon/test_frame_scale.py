"""The downscale's bookkeeping between the capture and landmark stages: the ring's FrameRef carries the factor and
the source's size through JSON and pickle, and landmarks go back to the source's pixels (x, y, z; not
visibility or presence); hal's whole-factor sizes."""

from __future__ import annotations

import json
import pickle
import time

import numpy as np
import pytest

from posed import hal
from posed.daemon.messages import FrameRef
from posed.daemon.proc.ring import FrameRing
from posed.daemon.stages.landmark import to_source_pixels
from posed.landmarks import LandmarkFrame


@pytest.mark.parametrize(("size", "k", "working"), [
    ((1920, 1080), 2, (960, 540)), ((1080, 1920), 2, (540, 960)), ((1768, 994), 2, (884, 497)),
    ((3840, 2160), 3, (1280, 720)), ((1280, 720), 1, (1280, 720)), ((640, 480), 1, (640, 480)),
    ((1281, 720), 2, (640, 360)),
])
def test_whole_factors(size, k, working):
    assert hal.scale_factor(*size, 1280 * 720) == k
    assert hal.working_size(*size, 1280 * 720) == working


def test_downscale_averages_blocks_and_keeps_a_point_at_k_times():
    image = np.zeros((5, 7, 3), np.uint8)
    image[2:4, 4:6] = 200                       # one 2x2 block, at (4, 2) in the source: (2, 1) scaled
    out = hal.downscale(image, 2)
    assert out.shape == (2, 3, 3)               # the odd last row and column are left out
    assert out[1, 2, 0] == 200 and out.sum() == 200 * 3
    depth = np.arange(35, dtype=np.uint16).reshape(5, 7)
    d = hal.downscale_depth(depth, 2)
    assert d.shape == (2, 3) and d[0, 0] == depth[1, 1] and d[1, 2] == depth[3, 5]   # block centres, unblended


def test_the_ring_carries_the_factor_and_the_source_size():
    ring = FrameRing.create(2, 960 * 540, False)
    try:
        ref = ring.write(np.zeros((540, 960, 3), np.uint8), 7, time.monotonic(), scale=2, source_size=(1920, 1080))
        assert (ref.width, ref.height, ref.scale, ref.full_size) == (960, 540, 2, (1920, 1080))
        assert FrameRef.from_json(json.loads(json.dumps(ref.to_json()))) == ref == pickle.loads(pickle.dumps(ref))
        plain = ring.write(np.zeros((480, 640, 3), np.uint8), 8, time.monotonic())
        assert (plain.scale, plain.full_size) == (1, (640, 480))
        assert FrameRef.from_json({k: v for k, v in plain.to_json().items() if k not in ("scale", "source_size")}) \
            == plain                            # a FrameRef written before these fields
    finally:
        ring.close()


def test_landmarks_go_back_to_the_source_pixels():
    lm = np.full((33, 5), np.nan)
    lm[0] = [100.0, 50.0, -20.0, 0.9, 0.8]
    frame = LandmarkFrame(seq=1, t=0.5, landmarks=lm)
    out = to_source_pixels(frame, 2)
    assert np.allclose(out.landmarks[0], [200.0, 100.0, -40.0, 0.9, 0.8]) and np.isnan(out.landmarks[1]).all()
    assert np.allclose(frame.landmarks[0, :3], [100.0, 50.0, -20.0])          # the input is not changed
    assert to_source_pixels(LandmarkFrame(seq=2, t=0.6, landmarks=None), 2).landmarks is None
