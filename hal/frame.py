"""One captured frame; the pinhole intrinsics of its colour image are a :class:`camera_model.Intrinsics`
(image and camera frames: see :mod:`camera_model.intrinsics`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from posed.camera_model import Intrinsics

SPECTRA = ("colour", "infrared")


@dataclass(frozen=True, eq=False)
class Frame:
    """An image (colour, or infrared at night), optionally depth aligned to it, and when it was captured.

    image        H x W x 3 uint8, BGR (treat as read-only)
    depth        H x W uint16 aligned to ``image`` (same pixel grid), 0 = no depth; or None
    depth_scale  metres per depth unit (0.0 when there is no depth)
    t            capture time, seconds on the ``time.monotonic()`` clock of this machine
    seq          frame number from the source (increasing; a gap means frames were lost)
    intrinsics   of ``image``, or None when unknown
    gravity      the direction of gravity (down), a unit vector in the axes of the camera that took ``image``
                 (x right, y down, z forward), from the camera's accelerometer (:mod:`hal.imu`); None without one
    spectrum     what ``image`` shows: ``colour`` (the colour camera's picture), or ``infrared`` (a RealSense's
                 left infrared imager in a dark room, :mod:`hal.night`: its grey image as BGR, ``intrinsics``,
                 ``gravity`` and ``depth`` then those of that imager)
    """

    image: np.ndarray
    depth: np.ndarray | None
    depth_scale: float
    t: float
    seq: int
    intrinsics: Intrinsics | None = None
    gravity: tuple[float, float, float] | None = None
    spectrum: str = "colour"

    def __post_init__(self) -> None:
        if self.spectrum not in SPECTRA:
            raise ValueError(f"Frame.spectrum must be one of {', '.join(SPECTRA)}, got {self.spectrum!r}")
        if self.gravity is not None:
            g = tuple(float(v) for v in self.gravity)
            if len(g) != 3 or not all(np.isfinite(g)) or abs(float(np.linalg.norm(g)) - 1.0) > 1e-6:
                raise ValueError(f"Frame.gravity must be a unit vector (3 finite numbers), got {self.gravity!r}")
            object.__setattr__(self, "gravity", g)
        img = self.image
        if not (isinstance(img, np.ndarray) and img.dtype == np.uint8 and img.ndim == 3 and img.shape[2] == 3):
            raise ValueError(f"Frame.image must be H x W x 3 uint8 BGR, got {getattr(img, 'shape', None)} "
                             f"{getattr(img, 'dtype', type(img).__name__)}")
        if self.depth is not None:
            d = self.depth
            if not (isinstance(d, np.ndarray) and d.dtype == np.uint16 and d.shape == img.shape[:2]):
                raise ValueError(f"Frame.depth must be uint16 {img.shape[:2]} (aligned to the image), got "
                                 f"{getattr(d, 'shape', None)} {getattr(d, 'dtype', type(d).__name__)}")

    @property
    def width(self) -> int:
        return int(self.image.shape[1])

    @property
    def height(self) -> int:
        return int(self.image.shape[0])

    def depth_m(self) -> np.ndarray | None:
        """Depth in metres (float32, 0 = none), or None."""
        if self.depth is None:
            return None
        return self.depth.astype(np.float32) * np.float32(self.depth_scale)
