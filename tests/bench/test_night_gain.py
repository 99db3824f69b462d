"""bench.night_gain (``posed bench night``'s ``+gain`` conditions): the gain on dim frames, against plain NumPy
references. The tables are checked value by value against the sRGB transfer function written out here
(IEC 61966-2-1), the gain against its definition (threshold, target, cap)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from posed.bench import night_gain as ll


def to_linear(v8: float) -> float:
    c = v8 / 255.0
    return c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4


def to_srgb8(c: float) -> float:
    c = min(max(c, 0.0), 1.0)
    s = c * 12.92 if c <= 0.0031308 else 1.055 * c ** (1 / 2.4) - 0.055
    return 255.0 * s


def reference_table(gain: float, space: str) -> np.ndarray:
    if space == "srgb":
        values = [min(255.0, v * gain) for v in range(256)]
    else:
        values = [to_srgb8(to_linear(v) * gain) for v in range(256)]
    return np.array([math.floor(x + 0.5) for x in values], dtype=np.uint8)


def flat(value: int, shape=(96, 128)) -> np.ndarray:
    return np.full((*shape, 3), value, np.uint8)


def test_target_is_mid_grey_through_the_srgb_curve():
    assert to_srgb8(0.18) == pytest.approx(117.65, abs=0.01)
    assert round(to_srgb8(0.18)) == ll.TARGET


@pytest.mark.parametrize("space", ll.SPACES)
@pytest.mark.parametrize("gain", [1.0, 1.7, 3.0, 9.39, 16.0])
def test_table_matches_the_numpy_reference(space, gain):
    table = ll.gain_table(gain, space)
    assert table.dtype == np.uint8 and table.shape == (256,)
    ref = reference_table(gain, space)
    # a value landing within rounding error of a half may round the other way: one unit, at most 2 entries
    assert np.abs(table.astype(int) - ref.astype(int)).max() <= 1
    assert (table != ref).sum() <= 2
    if gain == 1.0:
        assert np.array_equal(table, np.arange(256, dtype=np.uint8))
    assert np.all(np.diff(table.astype(int)) >= 0) and table[255] == 255


def test_linear_and_srgb_tables_differ():
    """Both at 4x: on 8-bit values v -> 4v; in linear light mid-dark values gain far less than 4x their value."""
    assert ll.gain_table(4.0, "srgb")[20] == 80
    assert 30 < ll.gain_table(4.0, "linear")[20] < 60


def test_gain_threshold_target_and_cap():
    lin = to_linear
    # at or above the threshold: no gain
    assert ll.gain_for(ll.THRESHOLD) == 1.0 and ll.gain_for(200.0) == 1.0
    # just below: the full gain to the target, linear in light or on the values
    y = ll.THRESHOLD - 0.5
    assert ll.gain_for(y, space="linear") == pytest.approx(lin(ll.TARGET) / lin(y), rel=1e-9)
    assert ll.gain_for(y, space="srgb") == pytest.approx(ll.TARGET / y, rel=1e-12)
    assert ll.gain_for(y) == ll.gain_for(y, space=ll.SPACE)
    # the cap
    assert ll.gain_for(5.0) == ll.MAX_GAIN and ll.TARGET / 5.0 > ll.MAX_GAIN
    assert ll.gain_for(5.0, space="linear") == ll.MAX_GAIN and ll.gain_for(8.0) < ll.MAX_GAIN
    assert ll.gain_for(0.0) == ll.MAX_GAIN
    assert ll.gain_for(5.0, space="srgb", max_gain=4.0) == 4.0
    # never below 1 (a target under the threshold)
    assert ll.gain_for(30.0, target=20.0) == 1.0
    with pytest.raises(ValueError, match="linear, srgb"):
        ll.gain_for(10.0, space="log")


@pytest.mark.parametrize("space", ll.SPACES)
def test_apply_brings_a_flat_dim_frame_to_the_target(space):
    low = ll.LowLight(space=space)
    image = flat(30)
    out, g = low.apply(image)
    assert out.dtype == np.uint8 and out.shape == image.shape and out is not image
    assert g == pytest.approx(ll.gain_for(30.0, space=space))
    assert ll.mean_luma(out) == pytest.approx(ll.TARGET, abs=0.6)
    assert np.array_equal(image, flat(30))            # the caller's frame is not changed


def test_apply_is_the_table_on_every_pixel_and_a_no_op_above_the_threshold():
    rng = np.random.default_rng(5)
    dim = (rng.random((61, 83, 3)) * 50).astype(np.uint8)
    low = ll.LowLight()
    out, g = low.apply(dim)
    assert g > 1.0
    assert np.abs(out.astype(int) - reference_table(g, ll.SPACE)[dim].astype(int)).max() <= 1
    assert np.array_equal(out, ll.gain_table(g)[dim])
    bright = (rng.random((61, 83, 3)) * 255).astype(np.uint8)
    assert ll.mean_luma(bright) > ll.THRESHOLD
    same, g = low.apply(bright)
    assert same is bright and g == 1.0


def test_just_below_the_threshold_applies_and_at_it_does_not():
    low = ll.LowLight()
    below, g_below = low.apply(flat(39))
    at, g_at = low.apply(flat(40))
    assert g_below > 2.0 and ll.mean_luma(below) > 100
    assert g_at == 1.0 and np.array_equal(at, flat(40))


def test_bad_gains_are_refused():
    with pytest.raises(ValueError):
        ll.LowLight(max_gain=0.5)
    with pytest.raises(ValueError, match="linear, srgb"):
        ll.LowLight(space="log")
