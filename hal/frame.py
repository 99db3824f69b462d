"""One captured frame and the pinhole intrinsics of its colour image.

Image frame: pixels, x to the right, y down, origin at the centre of the top-left pixel (OpenCV and
librealsense convention). Camera frame: metres, x right, y down, z forward (along the optical axis).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Intrinsics:
    """Pinhole intrinsics in pixels of a ``width`` x ``height`` image (no lens distortion)."""

    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int

    def scaled(self, width: int, height: int) -> Intrinsics:
        """The same camera seen at another resolution (a pure resize of the image)."""
        if (width, height) == (self.width, self.height):
            return self
        sx, sy = width / self.width, height / self.height
        return Intrinsics(self.fx * sx, self.fy * sy, (self.cx + 0.5) * sx - 0.5, (self.cy + 0.5) * sy - 0.5,
                          int(width), int(height))

    def deproject(self, u: np.ndarray | float, v: np.ndarray | float, z_m: np.ndarray | float) -> np.ndarray:
        """Camera-frame points (..., 3) in metres of pixels (u, v) at depth ``z_m`` (metres along z)."""
        u, v, z = np.broadcast_arrays(np.asarray(u, float), np.asarray(v, float), np.asarray(z_m, float))
        return np.stack([(u - self.cx) / self.fx * z, (v - self.cy) / self.fy * z, z], axis=-1)

    def project(self, xyz_m: np.ndarray) -> np.ndarray:
        """Pixels (..., 2) of camera-frame points (..., 3) in metres (z > 0)."""
        p = np.asarray(xyz_m, float)
        return np.stack([self.fx * p[..., 0] / p[..., 2] + self.cx, self.fy * p[..., 1] / p[..., 2] + self.cy],
                        axis=-1)

    def to_json(self) -> dict:
        return {"fx": self.fx, "fy": self.fy, "cx": self.cx, "cy": self.cy, "width": self.width,
                "height": self.height}

    @classmethod
    def from_json(cls, obj: dict) -> Intrinsics:
        return cls(float(obj["fx"]), float(obj["fy"]), float(obj["cx"]), float(obj["cy"]), int(obj["width"]),
                   int(obj["height"]))


@dataclass(frozen=True, eq=False)
class Frame:
    """A colour image, optionally depth aligned to it, and when it was captured.

    image        H x W x 3 uint8, BGR (treat as read-only)
    depth        H x W uint16 aligned to ``image`` (same pixel grid), 0 = no depth; or None
    depth_scale  metres per depth unit (0.0 when there is no depth)
    t            capture time, seconds on the ``time.monotonic()`` clock of this machine
    seq          frame number from the source (increasing; a gap means frames were lost)
    intrinsics   of ``image``, or None when unknown
    """

    image: np.ndarray
    depth: np.ndarray | None
    depth_scale: float
    t: float
    seq: int
    intrinsics: Intrinsics | None = None

    def __post_init__(self) -> None:
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
