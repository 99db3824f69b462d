"""A gain on a dark frame before posed's landmark stage sees it (``posed bench night``'s ``+gain`` conditions):
measured, not adopted — the stage takes frames as they come.

BlazePose takes raw pixel values (the detector ``px/127.5 − 1``, the landmark model ``px/255``: no brightness
normalisation) and was trained on normally exposed photos. The hypothesis measured here: a frame whose mean
luma (``hal.mean_luma``: BT.601 weights over every 8th row and column, the measure of the daemon's night
switch) is below ``THRESHOLD``, brightened towards ``TARGET`` by one gain for the whole frame,
applied as a 256-entry table (``cv2.LUT``) to every pixel, shows the stage people it loses otherwise (the image
keeps its size, so landmark coordinates are those of the frame as it came).

* ``TARGET`` = 118: the photographic mid-grey, 18 % reflectance (the Kodak grey card, the reflectance a
  reflected-light meter's calibration stands for), put through the sRGB transfer function (IEC 61966-2-1):
  ``1.055 · 0.18^(1/2.4) − 0.055`` = 0.4614, × 255 = 117.6.
* ``THRESHOLD`` = 40: from the measured loss, not from these gains (``posed bench night``,
  docs/bench/landmarks.md, "In the dark"): on six real scenes the stage first lost people at a mean luma of
  28.6 at most, and one halving of the light above that is about 40 (halving the light at these levels moves
  the mean luma by a factor of about 1.4: 25 -> 37, 18 -> 25 in that bench). Above it the frame is untouched.
* The gain is a factor on the 8-bit values (:data:`SPACE` ``srgb``): ``v -> min(255, g·v)`` with
  ``g = TARGET / mean luma``, so the frame's mean luma becomes the target (less what clips at 255). The
  other space, ``linear`` (each value to linear light by the sRGB transfer function, times ``g``, clipped at 1,
  back to 8-bit sRGB: what more exposure would have given, noise aside; ``g = lin(TARGET) / lin(mean luma)``),
  was measured beside it and found fewer people at the darkest levels (docs/bench/landmarks.md, "A gain on
  dim frames"): it lifts the darkest values, where the noise is, most.
* ``MAX_GAIN`` = 16: a bound on how much noise is amplified, set before measuring (four stops in linear
  light, about the whole analog gain range of the D435's colour sensor, OV2740, 15.5×, once more). On the
  8-bit values it is reached only below a mean luma of 118 / 16 = 7.4, darker than any frame measured.

Measured (``posed bench night``, docs/bench/landmarks.md "A gain on dim frames"): on the whole the gain did not
recover people — more frames found on some scenes, fewer on others, fewer just below the threshold, and the two
untouched clips disagree — so the landmark stage does not apply it. Cost, had it been adopted: 0.41 ms per frame
at 640x480, 1.4 ms at 1280x720 (a mean over 1/64 of the pixels and one table lookup per byte).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from posed.bench.night_sensor import linear_to_srgb, srgb_to_linear
from posed.hal import mean_luma

SPACES = ("linear", "srgb")
SPACE = "srgb"
TARGET = 118.0
THRESHOLD = 40.0
MAX_GAIN = 16.0


def gain_for(luma: float, *, space: str = SPACE, target: float = TARGET, threshold: float = THRESHOLD,
             max_gain: float = MAX_GAIN) -> float:
    """The gain for a frame of mean luma ``luma``: 1 at or above ``threshold``; below it the factor that
    brings the mean to ``target`` (in ``space``), at most ``max_gain`` and at least 1."""
    if space not in SPACES:
        raise ValueError(f"gain space {space!r} is not one of: {', '.join(SPACES)}")
    if not luma < threshold:
        return 1.0
    if luma <= 0.0:
        return float(max_gain)
    if space == "srgb":
        g = target / luma
    else:
        g = float(srgb_to_linear(target / 255.0)) / float(srgb_to_linear(luma / 255.0))
    return float(min(max(g, 1.0), max_gain))


def gain_table(gain: float, space: str = SPACE) -> np.ndarray:
    """The 256-entry uint8 table of ``gain`` in ``space`` (``linear``: in linear light; ``srgb``: on the
    8-bit values), rounded to the nearest value (halves up) and clipped at 255 (about 30 us to build)."""
    if space not in SPACES:
        raise ValueError(f"gain space {space!r} is not one of: {', '.join(SPACES)}")
    v = np.arange(256, dtype=np.float64)
    if space == "srgb":
        out = v * float(gain)
    else:
        out = linear_to_srgb(np.minimum(srgb_to_linear(v / 255.0) * float(gain), 1.0)) * 255.0
    return np.clip(np.floor(out + 0.5), 0, 255).astype(np.uint8)


@dataclass(frozen=True)
class LowLight:
    """The gain (module doc); :meth:`apply` gives the image the landmark stage is shown."""

    threshold: float = THRESHOLD
    target: float = TARGET
    max_gain: float = MAX_GAIN
    space: str = SPACE

    def __post_init__(self) -> None:
        if self.space not in SPACES:
            raise ValueError(f"gain space {self.space!r} is not one of: {', '.join(SPACES)}")
        if not (0.0 < self.threshold <= 255.0 and 0.0 < self.target <= 255.0 and self.max_gain >= 1.0):
            raise ValueError(f"low light: threshold and target in (0, 255], max_gain >= 1 (got {self.threshold}, "
                             f"{self.target}, {self.max_gain})")

    def gain(self, luma: float) -> float:
        return gain_for(luma, space=self.space, target=self.target, threshold=self.threshold,
                        max_gain=self.max_gain)

    def apply(self, image: np.ndarray) -> tuple[np.ndarray, float]:
        """(the image the models see, the gain): the image itself (not a copy) when the gain is 1."""
        g = self.gain(mean_luma(image))
        if g == 1.0:
            return image, 1.0
        return cv2.LUT(image, gain_table(g, self.space)), g
