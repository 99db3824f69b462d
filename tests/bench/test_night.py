"""bench.night_sensor and bench.night (``posed bench night``).

The sensor model is checked against plain NumPy computations of what it should give (the mean level held by
the auto-exposure, the noise variance growing with the signal as shot noise does, the gain clamped at the
sensor's maximum, the image darkening past it); the dot pattern for being seeded and repeatable; and one small
real run of the bench: the first frames of the real squat video through posed's real landmark stage.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from posed.bench import night
from posed.bench import night_sensor as ns

SHARED = Path(__file__).resolve().parents[2].parent / "shared" / "data"
SENSOR = ns.Sensor("test", full_well_e=4000.0, read_noise_e=2.0, max_gain=16.0, adc_bits=12)


def flat(value: int, size: int = 256) -> np.ndarray:
    return np.full((size, size, 3), value, np.uint8)


def linear(v8: float) -> float:
    """sRGB 8-bit to linear, written out on its own (IEC 61966-2-1)."""
    c = v8 / 255.0
    return c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4


def test_srgb_round_trip_and_formula():
    v = np.arange(256) / 255.0
    assert np.allclose(ns.linear_to_srgb(ns.srgb_to_linear(v)), v, atol=1e-12)
    assert ns.srgb_to_linear(np.array([128 / 255]))[0] == pytest.approx(linear(128), rel=1e-12)


def test_mean_level_held_by_auto_exposure_until_max_gain():
    """Above the gain clamp the output's mean is the original's (the AE target); the gain is 1/f."""
    rng = np.random.default_rng(1)
    image = flat(120)
    for f in (1.0, 1 / 4, 1 / 15):
        d = ns.dim(image, f, rng, SENSOR)
        assert d.gain == pytest.approx(1 / f, rel=0.01)
        assert not d.clamped
        assert ns.mean_luma(d.image) == pytest.approx(120, abs=1.5)


def test_gain_clamped_and_image_darkens_past_max_gain():
    """Past 1/max_gain the gain stays at max_gain and the linear mean falls as f x max_gain of the original's
    (the NumPy reference: the output taken back to linear light with the sRGB formula written out here)."""
    rng = np.random.default_rng(2)
    image = flat(120, 512)
    to_linear = np.array([linear(v) for v in range(256)])
    previous = 255.0
    for f in (1 / 32, 1 / 64, 1 / 128):
        d = ns.dim(image, f, rng, SENSOR)
        assert d.clamped and d.gain == SENSOR.max_gain
        got = float(to_linear[d.image].mean())
        assert got == pytest.approx(linear(120) * f * SENSOR.max_gain, rel=0.03)
        assert ns.mean_luma(d.image) < previous - 10
        previous = ns.mean_luma(d.image)


def test_noise_variance_grows_with_the_signal_as_shot_noise():
    """Variance in electrons = signal + read noise^2: measured on the output mapped back to electrons."""
    rng = np.random.default_rng(3)
    full = 2 ** SENSOR.adc_bits - 1
    for v8 in (60, 120, 200):
        f = 1 / 16
        d = ns.dim(flat(v8, 512), f, rng, SENSOR)
        # back to electrons: 8-bit sRGB -> linear -> / gain x full well (the 8-bit output's quantisation adds
        # its own variance; it is estimated from the sRGB slope and subtracted)
        lin = np.array([linear(v) for v in range(256)])[d.image]
        e = lin * SENSOR.full_well_e / d.gain
        mean_e = linear(v8) * SENSOR.full_well_e * f
        slope = (linear(min(v8 + 1, 255)) - linear(v8 - 1)) / 2 * SENSOR.full_well_e / d.gain   # e per 8-bit step
        quant = slope ** 2 / 12 + (SENSOR.full_well_e / full / d.gain) ** 2 / 12
        assert e.mean() == pytest.approx(mean_e, rel=0.03)
        assert e.var() - quant == pytest.approx(mean_e + SENSOR.read_noise_e ** 2, rel=0.15)


def test_shot_noise_is_poisson_like_on_both_sides_of_the_switch():
    rng = np.random.default_rng(4)
    for lam in (3.0, 30.0, 300.0):
        x = ns.shot_noise(np.full(200_000, lam), rng)
        assert x.mean() == pytest.approx(lam, rel=0.02)
        assert x.var() == pytest.approx(lam, rel=0.03)


def test_dim_is_seeded():
    image = (np.random.default_rng(0).random((64, 64, 3)) * 255).astype(np.uint8)
    a = ns.dim(image, 1 / 64, np.random.default_rng(7)).image
    b = ns.dim(image, 1 / 64, np.random.default_rng(7)).image
    c = ns.dim(image, 1 / 64, np.random.default_rng(8)).image
    assert np.array_equal(a, b) and not np.array_equal(a, c)


def test_gray_is_bt601_luma_on_three_channels():
    image = np.zeros((2, 2, 3), np.uint8)
    image[0, 0] = (0, 0, 255)      # red (BGR)
    image[0, 1] = (0, 255, 0)
    image[1, 0] = (255, 0, 0)
    g = ns.gray(image)
    assert g[0, 0].tolist() == [76] * 3 and g[0, 1].tolist() == [150] * 3 and g[1, 0].tolist() == [29] * 3
    assert ns.mean_luma(image) == pytest.approx(76.245)        # every 8th row and column: pixel (0, 0) only
    big = (np.random.default_rng(9).random((40, 48, 3)) * 255).astype(np.uint8)
    sub = big[::8, ::8].astype(float)
    assert ns.mean_luma(big) == pytest.approx((0.299 * sub[..., 2] + 0.587 * sub[..., 1] + 0.114 * sub[..., 0]).mean())


def test_dot_pattern_seeded_repeatable_and_counted():
    a = ns.dot_pattern(400, 640, seed=5)
    b = ns.dot_pattern(400, 640, seed=5)
    c = ns.dot_pattern(400, 640, seed=6)
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    # a lone spot peaks at 1; the total over the image is the dots times one spot's integral (2 pi sigma^2)
    sigma = ns.DOT_SIGMA_PX * 640 / ns.DOT_REF_WIDTH
    lone = ns.dot_pattern(101, 101, seed=0, dots=1, sigma_px=2.0)
    assert lone.max() == pytest.approx(1.0, abs=1e-5)
    inside = ns.dot_pattern(400, 640, seed=5, sigma_px=sigma)
    assert inside.sum() == pytest.approx(ns.DOTS * 2 * np.pi * sigma ** 2, rel=0.05)


def test_with_dots_brightness_relative_to_the_scene():
    image = flat(100, 128)
    pattern = np.zeros((128, 128), np.float32)
    pattern[10, 10] = 1.0
    out = ns.with_dots(image, pattern, 0.5)
    assert out[10, 10].tolist() == [150] * 3 and out[50, 50].tolist() == [100] * 3


def test_thresholds_from_the_dim_rows():
    rows = [{"kind": "colour", "value": 1.0, "found_rate": 1.0, "mean_luma_median": 150}]
    rates = (1.0, 1.0, 0.97, 0.9, 0.5, 0.0)
    rows += [{"kind": "dim", "value": 2.0 ** -k, "found_rate": r, "mean_luma_median": 150 / 2 ** k}
             for k, r in enumerate(rates)]
    t = night.thresholds(rows)
    assert t["95%"]["held_to"]["f"] == 1 / 4 and t["95%"]["lost_at"]["f"] == 1 / 8
    assert t["80%"]["held_to"]["f"] == 1 / 8 and t["80%"]["lost_at"]["f"] == 1 / 16
    assert t["95%"]["dips"] == [] and t["95%"]["lost_at"]["mean_luma"] == 150 / 8
    rows[2]["found_rate"] = 0.94           # one frame lost at 1/2 (noise): a dip, not the threshold
    t = night.thresholds(rows)
    assert t["95%"]["held_to"]["f"] == 1 / 4 and t["95%"]["lost_at"]["f"] == 1 / 8
    assert [d["f"] for d in t["95%"]["dips"]] == [1 / 2]
    # a +gain row (the same frames, the stage's gain on) is not a light level of its own
    with_gain = rows + [{"kind": "dim", "value": 1 / 2, "found_rate": 0.0, "mean_luma_median": 75, "gain": "linear"}]
    assert night.thresholds(with_gain) == t
    assert night.thresholds(rows[:1] + with_gain[-1:]) == {}     # `--only` some +gain rows: nothing to read
    for r in rows[1:]:
        r["found_rate"] = 1.0
    t = night.thresholds(rows)
    assert t["80%"]["lost_at"] is None and t["80%"]["held_to"]["f"] == 1 / 32


def test_match_needs_overlap():
    ref = np.zeros((33, 5))
    ref[:, 0] = np.linspace(100, 200, 33)
    ref[:, 1] = np.linspace(100, 400, 33)
    moved = ref.copy()
    moved[:, 0] += 500
    assert night.match(ref, [moved]) is None
    assert night.match(ref, [moved, ref]) is ref


@pytest.fixture(scope="module")
def small_run():
    if not (SHARED / night.VIDEOS[0][1]).is_file():
        pytest.fail(f"shared test data missing: {SHARED / night.VIDEOS[0][1]} (the bench needs the real squat video)")
    from posed.daemon.config import load_config

    config = load_config(None)
    conds = [night.Condition("colour", "colour", 1.0), night.Condition("colour f=1/1", "dim", 1.0),
             night.Condition("colour f=1/4096", "dim", 1 / 4096), night.Condition("gray", "gray", 1.0),
             night.Condition("gray+dots x2", "dots", 2.0), night.Condition("colour f=1/512", "dim", 1 / 512),
             night.Condition("gray f=1/128", "gray_dim", 1 / 128)]
    conds += [night.gained(c) for c in conds[5:]] + [night.gained(conds[1]), night.gained(conds[5], "linear")]
    return night.run_bench(SHARED, config, quick=4, conds=conds)


def test_small_real_run(small_run):
    report = json.loads(json.dumps(small_run))        # JSON-able
    (source,) = report["sources"]
    assert source["source"] == "squat" and source["frames"] == 4
    rows = {r["condition"]: r for r in source["rows"]}
    assert set(rows) == {"colour", "colour f=1/1", "colour f=1/4096", "gray", "gray+dots x2", "colour f=1/512",
                         "gray f=1/128", "colour f=1/512 +gain", "gray f=1/128 +gain", "colour f=1/1 +gain",
                         "colour f=1/512 +gain linear"}
    for r in rows.values():
        assert {"found", "reference_frames", "found_rate", "dev_px_median", "dev_px_p90", "dev_torso_median",
                "dev_torso_p90", "mean_luma_median"} <= set(r)
    original = rows["colour"]
    assert original["reference_frames"] == 4 and original["found_rate"] == 1.0
    assert original["dev_px_p90"] == 0.0
    dark = rows["colour f=1/4096"]
    assert dark["mean_luma_median"] < 15 < original["mean_luma_median"]
    assert dark["found"] < original["found"]
    assert rows["colour f=1/1"]["found_rate"] == 1.0 and 0 < rows["colour f=1/1"]["dev_px_median"] < 10
    assert rows["gray"]["found_rate"] == 1.0 and rows["gray"]["dev_px_median"] > 0.0
    lines = night.table(report)
    assert any(line.startswith("squat") and "colour f=1/4096" in line for line in lines)
    assert any(line.startswith("squat") and "colour f=1/512 +gain linear" in line and " -> " in line for line in lines)
    assert "held to" in lines[-1]


def test_small_real_run_gain_conditions(small_run):
    """A ``+gain`` row runs the frames of its base row (the same seed, so the same mean luma) brightened by
    the gain before the landmark stage sees them: above the threshold (full light; gray at 1/128, luma ~56) it changes nothing, to
    the field; below it (colour at 1/512, luma ~25) the models see a frame brightened towards the target (and
    find the woman on frames where she is lost without it); the thresholds are read from the rows without the
    gain."""
    from posed.bench import night_gain as ll

    (source,) = small_run["sources"]
    rows = {r["condition"]: r for r in source["rows"]}
    for base in ("colour f=1/1", "gray f=1/128"):
        same = {k: v for k, v in rows[base + " +gain"].items()
                if k not in ("condition", "gain", "gain_median", "gained_luma_median")}
        assert rows[base]["mean_luma_median"] > ll.THRESHOLD
        assert same == {k: v for k, v in rows[base].items() if k != "condition"}
        assert rows[base + " +gain"]["gain_median"] == 1.0
    dim, srgb, lin = rows["colour f=1/512"], rows["colour f=1/512 +gain"], rows["colour f=1/512 +gain linear"]
    assert "gain" not in dim and lin["gain"] == "linear" and srgb["gain"] == "srgb" == ll.SPACE
    assert lin["mean_luma_median"] == dim["mean_luma_median"] == srgb["mean_luma_median"] < ll.THRESHOLD
    assert srgb["gain_median"] == pytest.approx(ll.gain_for(dim["mean_luma_median"]), rel=0.05)
    assert lin["gain_median"] == pytest.approx(ll.gain_for(dim["mean_luma_median"], space="linear"), rel=0.05)
    assert lin["gained_luma_median"] > 80 and srgb["gained_luma_median"] == pytest.approx(ll.TARGET, abs=2)
    # measured on these 4 frames: none found as they come, all 4 with either gain
    assert dim["found"] < lin["found"] and dim["found"] < srgb["found"]
    assert source["thresholds"] == night.thresholds([r for r in source["rows"] if not r.get("gain")])



def test_dark_room_dots_show_the_lit_scene_at_the_dots():
    """``gray f=1/N+dots xK``: the dots peak at K x the lit gray image there, over a dark image; seeded."""
    image = np.zeros((200, 320, 3), np.uint8)
    image[:, :160] = 40
    image[:, 160:] = 200
    cond = night.Condition("gray f=1/512+dots x1", "dark_dots", 1 / 512, 1.0)
    out, y = night.transform(cond, 11, image.shape[:2])(image)
    again, _ = night.transform(cond, 11, image.shape[:2])(image)
    assert np.array_equal(out, again) and y == ns.mean_luma(out)
    pattern = ns.dot_pattern(200, 320, 11)
    lone = (pattern > 0.95) & (pattern < 1.05)          # centres of spots that do not overlap another
    for cols, lit in ((slice(0, 150), 40), (slice(170, 320), 200)):
        dark = np.median(out[..., 0][:, cols][pattern[:, cols] < 1e-3])
        assert dark < lit / 2
        peaks = out[..., 0][:, cols][lone[:, cols]].astype(float)
        assert np.median(peaks) - dark == pytest.approx(lit, abs=8)
