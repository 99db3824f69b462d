import numpy as np

from posed.landmarks.anchors import NUM_ANCHORS, ssd_anchor_centres


def test_pose_detector_has_2254_anchors_in_three_grids():
    a = ssd_anchor_centres()
    assert a.shape == (NUM_ANCHORS, 2) == (2254, 2)
    # 28x28 cells x 2, then 14x14 x 2, then 7x7 x 6 (three stride-32 layers merged)
    assert np.allclose(a[0], [0.5 / 28, 0.5 / 28]) and np.allclose(a[1], a[0])
    assert np.allclose(a[2], [1.5 / 28, 0.5 / 28])
    assert np.allclose(a[2 * 28], [0.5 / 28, 1.5 / 28])  # row-major: the next row starts after 28 cells
    assert np.allclose(a[1568], [0.5 / 14, 0.5 / 14])
    assert np.allclose(a[1568 + 392], [0.5 / 7, 0.5 / 7])
    assert np.allclose(a[1568 + 392: 1568 + 392 + 6], a[1568 + 392])
    assert np.allclose(a[-1], [6.5 / 7, 6.5 / 7])
    assert (a > 0).all() and (a < 1).all()


def test_generic_layers_merge_equal_strides():
    a = ssd_anchor_centres(input_size=64, strides=(16, 32, 32), anchors_per_layer=2)
    assert a.shape == (4 * 4 * 2 + 2 * 2 * 4, 2)
