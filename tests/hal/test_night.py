"""hal.night on plain NumPy images: the colour image's mean luma against a plain reference, and the chooser's
hysteresis, blank rule and modes."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from posed.hal.night import DARK_LUMA_ENTER, DARK_LUMA_LEAVE, LUMA_STEP, SpectrumChooser, mean_luma


@pytest.fixture(scope="module")
def photo(shared_data) -> np.ndarray:
    """The real MediaPipe pose photo (one man, full body), 500x333 BGR."""
    path = shared_data / "reference" / "mediapipe_pose_jpg" / "pose.jpg"
    image = cv2.imread(str(path))
    assert image is not None, f"missing real test image {path}"
    return cv2.resize(image, (500, 333), interpolation=cv2.INTER_AREA)


def reference_luma(image: np.ndarray) -> float:
    """BT.601 luma, pixel by pixel, of every LUMA_STEP-th row and column, averaged."""
    total, n = 0.0, 0
    for y in range(0, image.shape[0], LUMA_STEP):
        for x in range(0, image.shape[1], LUMA_STEP):
            b, g, r = (float(c) for c in image[y, x])
            total += 0.299 * r + 0.587 * g + 0.114 * b
            n += 1
    return total / n


def at_luma(photo: np.ndarray, luma: float) -> np.ndarray:
    """The photo scaled to a mean luma of about ``luma`` (a real scene, dimmer or brighter)."""
    return np.clip(photo.astype(np.float64) * (luma / mean_luma(photo)), 0, 255).round().astype(np.uint8)


def test_mean_luma_matches_a_plain_reference(photo):
    rng = np.random.default_rng(3)
    images = [photo, photo[1:, 3:], rng.integers(0, 256, (97, 61, 3), dtype=np.uint8),
              np.full((8, 8, 3), (10, 200, 30), np.uint8)]
    for image in images:
        assert mean_luma(image) == pytest.approx(reference_luma(image), abs=1e-9)
    # the weights: pure blue, green and red
    for bgr, y in (((255, 0, 0), 0.114 * 255), ((0, 255, 0), 0.587 * 255), ((0, 0, 255), 0.299 * 255)):
        assert mean_luma(np.full((16, 16, 3), bgr, np.uint8)) == pytest.approx(y)
    with pytest.raises(ValueError, match="H x W x 3"):
        mean_luma(np.zeros((4, 4), np.uint8))


def test_thresholds_leave_a_band_between_dark_and_light_again():
    assert 0.0 < DARK_LUMA_ENTER < DARK_LUMA_LEAVE < 255.0


def test_hysteresis_switches_below_enter_and_back_above_leave(photo):
    chooser = SpectrumChooser("auto")
    enter, leave = DARK_LUMA_ENTER, DARK_LUMA_LEAVE
    lumas = [120, leave - 5, enter + 1, enter - 1, enter - 10, leave - 5, leave - 1, leave + 1, leave - 5, enter + 1,
             enter - 1]
    got = [chooser.choose(at_luma(photo, y), True) for y in lumas]
    assert chooser.luma == pytest.approx(enter - 1, abs=0.1)
    assert got == ["colour", "colour", "colour", "infrared", "infrared", "infrared", "infrared", "colour", "colour",
                   "colour", "infrared"]


def test_dark_without_an_infrared_image_stays_colour_and_keeps_the_state(photo):
    chooser = SpectrumChooser()
    assert chooser.choose(at_luma(photo, DARK_LUMA_ENTER - 10), False) == "colour"  # dark, nothing else to show
    assert chooser.dark
    assert chooser.choose(at_luma(photo, DARK_LUMA_LEAVE - 5), True) == "infrared"  # still dark: not above leave


def test_a_blank_colour_frame_gives_way_to_infrared_at_any_brightness(photo):
    chooser = SpectrumChooser()
    green = np.full((120, 160, 3), (0, 135, 0), np.uint8)                # a YUYV stream of zeros: flat green
    assert mean_luma(green) > DARK_LUMA_LEAVE
    assert chooser.choose(green, True) == "infrared"
    assert not chooser.dark                                              # blank is not dark: bright is bright
    assert chooser.choose(green, False) == "colour"                      # no infrared: the blank error's job
    assert chooser.choose(at_luma(photo, 120), True) == "colour"


def test_modes_off_and_always(photo):
    off, always = SpectrumChooser("off"), SpectrumChooser("always")
    for y in (5, 120):
        assert off.choose(at_luma(photo, y), True) == "colour"
        assert always.choose(at_luma(photo, y), True) == "infrared"
        assert always.choose(at_luma(photo, y), False) == "colour"
    assert off.choose(np.zeros((64, 64, 3), np.uint8), True) == "colour"   # off: a blank frame stays blank
    with pytest.raises(ValueError, match="auto, off, always"):
        SpectrumChooser("night")
    with pytest.raises(ValueError, match="below the light one"):
        SpectrumChooser("auto", enter=70, leave=60)


def test_a_frame_says_its_spectrum_and_refuses_another():
    from posed import hal

    image = np.zeros((4, 4, 3), np.uint8)
    assert hal.Frame(image, None, 0.0, 0.0, 0).spectrum == "colour"
    assert hal.Frame(image, None, 0.0, 0.0, 0, spectrum="infrared").spectrum == "infrared"
    with pytest.raises(ValueError, match="spectrum must be one of colour, infrared"):
        hal.Frame(image, None, 0.0, 0.0, 0, spectrum="ultraviolet")
