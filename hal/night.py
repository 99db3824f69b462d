"""Which image a frame carries, by the light: the colour camera's, or at night the infrared imager's.

A RealSense D4xx's infrared imagers see the room by infrared light when visible light is gone: an 850 nm
illuminator's, or, sparsely, its own projector's dots (which alone may not show a person: docs/hal.md). So in a
dark room its left infrared image can show the person the colour image no longer does. The
colour image's brightness decides: its mean luma (:func:`mean_luma`: BT.601 weights over every
``LUMA_STEP``-th row and column) below ``DARK_LUMA_ENTER`` makes it dark, above ``DARK_LUMA_LEAVE`` light
again, and in between it stays what it was (hysteresis: a lamp flickering near one threshold does not switch
the image back and forth). A blank colour frame (:func:`hal.blank.is_blank`: a covered lens, a sensor fault)
shows nobody at any brightness, so it gives way to an infrared image whenever one came with it.

``source.infrared`` (:data:`hal.config.INFRARED_MODES`): ``auto`` chooses as above, ``always`` takes the
infrared image whenever there is one, ``off`` never does. No pyrealsense2 here: plain NumPy images.
"""

from __future__ import annotations

import numpy as np

from posed.hal.blank import is_blank
from posed.hal.config import INFRARED_MODES

# Set from `posed bench night` (docs/bench/landmarks.md, "In the dark"): on six real scenes under a sensor model
# of the D435's colour camera, the landmark stage found the person on >= 95 % of frames down to a mean luma of
# 24.9-43.4 and first lost them at 16.8-28.6 (the brightest loss: 28.6). Infrared replaces colour only where
# colour is about to fail, not before: in the same bench a dark room lit by the projector's dots alone showed
# nobody in the infrared image, so without an infrared lamp that image can be worse than a dim colour one.
# Colour again above 40: the worst video still found every frame at 35.9, and 30 -> 40 is about 1.5x the light.
DARK_LUMA_ENTER = 30.0
DARK_LUMA_LEAVE = 40.0
LUMA_STEP = 8                           # every 8th row and column: 4800 pixels of 640x480
BT601 = (0.114, 0.587, 0.299)           # weights of B, G, R (Y' = 0.299 R + 0.587 G + 0.114 B)
COLOUR, INFRARED = "colour", "infrared"


def mean_luma(image: np.ndarray) -> float:
    """Mean BT.601 luma (0-255) of a BGR uint8 image (H x W x 3), over every ``LUMA_STEP``-th row and column."""
    if image.ndim != 3 or image.shape[2] != 3:
        raise ValueError(f"mean_luma needs an H x W x 3 BGR image, got shape {image.shape}")
    sample = image[::LUMA_STEP, ::LUMA_STEP].reshape(-1, 3)
    if sample.size == 0:
        return 0.0
    return float(sample.mean(axis=0) @ np.asarray(BT601))


class SpectrumChooser:
    """Per frame, ``colour`` or ``infrared`` (module doc); ``mode`` is ``source.infrared``. Keeps whether the
    room is dark between frames (the hysteresis), so one chooser follows one stream of frames."""

    def __init__(self, mode: str = "auto", enter: float = DARK_LUMA_ENTER, leave: float = DARK_LUMA_LEAVE) -> None:
        if mode not in INFRARED_MODES:
            raise ValueError(f"infrared mode {mode!r} is not one of: {', '.join(INFRARED_MODES)} (source.infrared)")
        if not 0.0 <= enter < leave:
            raise ValueError(f"the dark threshold ({enter}) must be below the light one ({leave}), both >= 0")
        self.mode = mode
        self.enter = float(enter)
        self.leave = float(leave)
        self.dark = False
        self.luma: float | None = None      # the last colour frame's mean luma (auto only)

    def choose(self, colour: np.ndarray, has_infrared: bool) -> str:
        """The image to deliver for this colour frame (BGR) and whether an infrared image came with it."""
        if self.mode == "off":
            return COLOUR
        if self.mode == "always":
            return INFRARED if has_infrared else COLOUR
        self.luma = mean_luma(colour)
        if self.dark and self.luma > self.leave:
            self.dark = False
        elif not self.dark and self.luma < self.enter:
            self.dark = True
        if has_infrared and (self.dark or is_blank(colour)):
            return INFRARED
        return COLOUR
