"""``sample_depth`` and ``with_depth``: the depth at the landmarks, against a plain per-landmark NumPy reference and on the cases
that must give NaN (holes, landmarks outside the image, unknown landmarks) or a clipped patch (edges)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from posed.landmarks import LandmarkFrame, depth_patch_radius, sample_depth, with_depth

SCALE = 0.001


def reference(depth: np.ndarray, scale: float, landmarks: np.ndarray, r: int) -> np.ndarray:
    """One landmark at a time: nearest pixel, the (2r+1)² patch clipped to the image, the valid (non-zero)
    values sorted, the lower median if at least a quarter of the full patch is valid."""
    h, w = depth.shape
    out = np.full(len(landmarks), np.nan)
    for i, (x, y) in enumerate(landmarks[:, :2]):
        if not (math.isfinite(x) and math.isfinite(y)):
            continue
        u, v = math.floor(x + 0.5), math.floor(y + 0.5)
        if not (0 <= u < w and 0 <= v < h):
            continue
        patch = depth[max(0, v - r): v + r + 1, max(0, u - r): u + r + 1]
        valid = np.sort(patch[patch > 0].astype(np.float64))
        if len(valid) >= math.ceil((2 * r + 1) ** 2 / 4):
            out[i] = valid[(len(valid) - 1) // 2] * scale
    return out


def _landmarks(xy: np.ndarray) -> np.ndarray:
    lms = np.zeros((len(xy), 5))
    lms[:, :2] = xy
    lms[:, 3:] = 0.9
    return lms


def test_matches_the_reference_on_a_noisy_depth_image_with_holes():
    rng = np.random.default_rng(7)
    h, w = 480, 640
    depth = rng.integers(400, 6000, (h, w)).astype(np.uint16)
    depth[rng.uniform(size=(h, w)) < 0.3] = 0                     # scattered holes
    depth[100:160, 200:260] = 0                                    # one big hole
    xy = np.column_stack([rng.uniform(-20, w + 20, 400), rng.uniform(-20, h + 20, 400)])
    xy[:10] = [[0, 0], [w - 1, h - 1], [0, h - 1], [w - 1, 0], [-0.5, 10], [w - 0.5, 10],
               [-0.51, 10], [230, 130], [10.5, 10.5], [np.nan, 5]]
    lms = _landmarks(xy)
    for r in (0, 1, 2, 3, 5):
        assert np.array_equal(sample_depth(depth, SCALE, lms, radius=r), reference(depth, SCALE, lms, r),
                              equal_nan=True)
    got = sample_depth(depth, SCALE, lms)                           # default radius at 640x480: 2
    assert np.array_equal(got, reference(depth, SCALE, lms, 2), equal_nan=True)
    assert got.dtype == np.float64 and got.shape == (400,)
    assert np.isnan(got[7]) and np.isnan(got[9])                    # in the big hole; a NaN landmark
    assert 0.5 < np.isfinite(got).mean() < 1.0                      # both kinds of answer were compared


def test_flat_surface_gives_its_depth_in_metres():
    depth = np.full((480, 640), 1732, np.uint16)
    lms = _landmarks(np.array([[320.2, 240.7]] * 33))
    got = sample_depth(depth, 0.0010000000474974513, lms)          # the D4xx scale, a float32 0.001
    assert np.allclose(got, 1.732, atol=1e-6)


def test_holes_need_a_quarter_of_the_patch():
    depth = np.zeros((50, 50), np.uint16)
    lms = _landmarks(np.array([[25.0, 25.0]]))
    patch = [(v, u) for v in range(23, 28) for u in range(23, 28)]  # r = 2: 25 pixels, 7 must be valid
    for k, (v, u) in enumerate(patch[:6]):
        depth[v, u] = 1000 + k
    assert np.isnan(sample_depth(depth, SCALE, lms, radius=2)[0])
    depth[patch[6]] = 2000
    assert sample_depth(depth, SCALE, lms, radius=2)[0] == pytest.approx(1.003)   # lower median of 7


def test_even_count_takes_the_nearer_middle_value_at_a_silhouette_edge():
    depth = np.full((40, 40), 3000, np.uint16)                      # the wall
    depth[:, :20] = 1500                                            # the body, left half
    lms = _landmarks(np.array([[19.4, 20.0], [19.6, 20.0]]))        # nearest pixels 19 and 20: on each side
    got = sample_depth(depth, SCALE, lms, radius=2)
    assert got[0] == pytest.approx(1.5)                             # 15 body, 10 wall pixels
    assert got[1] == pytest.approx(3.0)                             # 10 body, 15 wall: the wall
    depth[0:40:2, :] = 0                                            # every other row a hole
    lms = _landmarks(np.array([[19.6, 21.0]]))                      # rows 19, 21, 23 valid: 6 body, 9 wall
    assert sample_depth(depth, SCALE, lms, radius=2)[0] == pytest.approx(3.0)
    lms = _landmarks(np.array([[19.6, 20.0]]))                      # rows 19, 21: 4 body, 6 wall -> 10 values
    assert sample_depth(depth, SCALE, lms, radius=2)[0] == pytest.approx(3.0)
    tie = np.zeros((10, 10), np.uint16)
    tie[3:5, 3:7] = [[1500, 1500, 3000, 3000], [1500, 1500, 3000, 3000]]   # 4 body, 4 wall: a tie
    got = sample_depth(tie, SCALE, _landmarks(np.array([[4.0, 4.0]])), radius=2)[0]
    assert got == pytest.approx(1.5)                                # the nearer one, not 2.25 (nothing there)


def test_outside_the_image_and_unknown_landmarks_are_nan():
    depth = np.full((30, 40), 2000, np.uint16)
    xy = np.array([[-0.51, 10], [-0.5, 10], [39.49, 10], [39.5, 10], [10, -0.6], [10, 29.5], [np.nan, 10],
                   [10, np.nan], [np.inf, 10]])
    got = sample_depth(depth, SCALE, _landmarks(xy), radius=1)
    assert np.array_equal(np.isnan(got), [True, False, False, True, True, True, True, True, True])
    assert np.allclose(got[[1, 2]], 2.0)
    lms = _landmarks(np.zeros((33, 2)))
    lms[:] = np.nan                                                 # a whole unknown frame
    assert np.isnan(sample_depth(depth, SCALE, lms)).all()


def test_edge_pixels_use_the_part_of_the_patch_inside_the_image():
    depth = np.zeros((30, 40), np.uint16)
    depth[0:2, 0:2] = [[1100, 1200], [1300, 1400]]                  # the 2x2 the r=1 patch at (0, 0) sees
    lms = _landmarks(np.array([[0.0, 0.0], [0.2, -0.4]]))
    assert np.allclose(sample_depth(depth, SCALE, lms, radius=1), [1.2, 1.2])  # 4 valid >= 3; lower median
    depth[0, 0] = depth[0, 1] = 0                                   # 2 valid of the 9-pixel patch: too few
    assert np.isnan(sample_depth(depth, SCALE, lms, radius=1)).all()


def test_default_radius_follows_the_image_size():
    assert [depth_patch_radius(w, h) for w, h in [(320, 240), (640, 480), (360, 640), (1280, 720),
                                                  (1920, 1080), (160, 120)]] == [1, 2, 2, 3, 5, 1]


@pytest.mark.parametrize("args, message", [
    ((np.zeros((4, 4), np.float32), SCALE, np.zeros((33, 5))), "H x W uint16"),
    ((np.zeros((4, 4, 1), np.uint16), SCALE, np.zeros((33, 5))), "H x W uint16"),
    ((np.zeros((4, 4), np.uint16), 0.0, np.zeros((33, 5))), "depth_scale must be a positive"),
    ((np.zeros((4, 4), np.uint16), float("nan"), np.zeros((33, 5))), "depth_scale must be a positive"),
    ((np.zeros((4, 4), np.uint16), SCALE, np.zeros(33)), "landmarks must be N x K"),
])
def test_bad_arguments_say_what_is_wrong(args, message):
    with pytest.raises(ValueError, match=message):
        sample_depth(*args)


def test_with_depth_fills_a_frame_only_when_there_is_depth_and_a_person():
    depth = np.full((30, 40), 2500, np.uint16)
    lms = _landmarks(np.full((33, 2), 10.0))
    person = LandmarkFrame(4, 0.4, lms, extra={"k": 1})
    filled = with_depth(person, depth, SCALE)
    assert filled.depth_m is not None and np.allclose(filled.depth_m, 2.5)
    assert (filled.seq, filled.t, filled.extra) == (4, 0.4, {"k": 1})
    assert np.array_equal(filled.landmarks, lms) and person.depth_m is None
    assert with_depth(person, None, SCALE) is person                 # no depth image
    assert with_depth(person, depth, 0.0) is person                  # depth scale unknown
    nobody = LandmarkFrame(5, 0.5, None)
    assert with_depth(nobody, depth, SCALE) is nobody
