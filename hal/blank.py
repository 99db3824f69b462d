"""Blank frames: a camera frame in which nothing can be seen because every pixel has the same colour.

All black (a covered lens, a closed privacy shutter, a pitch-dark room) or one flat colour (the uniform green a
YUYV stream of zeros converts to: a sensor or USB fault). A real scene, even a dim one, spans more than
``BLANK_RANGE`` levels in sensor noise alone. The live cameras (V4L2, RealSense, and RealSense recordings, which
replay what a RealSense saw) do not hand such a frame out: the read raises SourceCorrupt with
:func:`blank_message` and ``fix`` :data:`BLANK_FIX`, so the daemon counts it as a bad frame and says it is
blind, and why, instead of watching an empty room that is not empty.
"""

from __future__ import annotations

import numpy as np

# pixels sampled every BLANK_STEP rows and columns; blank when each channel spans at most BLANK_RANGE levels
BLANK_STEP = 8
BLANK_RANGE = 3
BLANK_FIX = ("uncover the camera's lens (privacy shutter, cap, something in front of it) and light the room; "
             "if it stays blank, check the camera's cable or replace the camera")


def is_blank(image: np.ndarray) -> bool:
    """True when every sampled pixel of ``image`` (H x W x C or H x W) has (nearly) the same colour."""
    channels = image.shape[2] if image.ndim == 3 else 1
    sample = image[::BLANK_STEP, ::BLANK_STEP].reshape(-1, channels)
    if sample.size == 0:
        return False
    return int((sample.max(axis=0).astype(np.int32) - sample.min(axis=0)).max()) <= BLANK_RANGE


def blank_message(image: np.ndarray) -> str:
    """What a blank BGR frame shows, for the error."""
    b, g, r = (int(v) for v in image[::BLANK_STEP, ::BLANK_STEP].reshape(-1, 3).mean(axis=0))
    shade = ", black" if max(b, g, r) < 16 else ""
    return (f"the camera sends blank frames (every pixel the same colour, BGR {b},{g},{r}{shade}): nobody can be "
            "seen in them (a covered lens, a closed privacy shutter, a completely dark room, or a sensor fault)")
