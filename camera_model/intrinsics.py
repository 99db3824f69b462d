"""The pinhole camera intrinsics every package uses, and the names of the capture times.

Image frame: pixels, x to the right, y down, origin at the centre of the top-left pixel (OpenCV and
librealsense convention). Camera frame: metres, x right, y down, z forward (along the optical axis).

Capture times, seconds on the one ``time.monotonic()`` clock of the machine (the daemon's clock):

* ``t_capture``: when the camera captured the frame (a hal ``Frame.t``, a ``LandmarkFrame.t`` of the live
  pipeline). It travels with the frame end to end and is the only clock used for fall timing.
* ``t_origin``: where latency counts from. It is the capture timestamp, except for unpaced replays, whose
  capture timestamps follow the recording's time line while frames are read as fast as the pipeline takes
  them: then it is the time the capture stage read the frame. A message carries ``t_origin = None`` when
  latency counts from ``t_capture``. Every message between the stages uses these two names.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

_FOCAL = ("fx", "fy", "cx", "cy")


@dataclass(frozen=True)
class Intrinsics:
    """Pinhole intrinsics in pixels of a ``width`` x ``height`` image (no lens distortion).

    ``fx``, ``fy``: focal lengths (> 0); ``cx``, ``cy``: principal point. The values are stored as float and
    int whatever numbers they were given as; non-finite or non-positive values raise ValueError.
    ``assumed``: not the camera's own intrinsics but a lens taken for granted because the source knows none
    (:meth:`assume`): image directions and relative depths through it are usable, distances in metres are not.
    """

    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int
    assumed: bool = False

    def __post_init__(self) -> None:
        try:
            focal = tuple(float(getattr(self, k)) for k in _FOCAL)
            size = (int(self.width), int(self.height))
        except (TypeError, ValueError):
            raise ValueError(f"intrinsics must be numbers, got {self!r}") from None
        if not all(math.isfinite(v) for v in focal) or focal[0] <= 0 or focal[1] <= 0:
            raise ValueError(f"intrinsics need finite fx, fy, cx, cy with fx, fy > 0, got {self!r}")
        if size != (self.width, self.height) or size[0] <= 0 or size[1] <= 0:
            raise ValueError(f"intrinsics need a positive integer width and height, got {self!r}")
        for k, v in zip((*_FOCAL, "width", "height"), (*focal, *size), strict=True):
            object.__setattr__(self, k, v)
        object.__setattr__(self, "assumed", bool(self.assumed))

    @property
    def size(self) -> tuple[int, int]:
        """``(width, height)`` of the image these intrinsics belong to."""
        return (self.width, self.height)

    @classmethod
    def from_hfov(cls, hfov_deg: float, width: int, height: int) -> Intrinsics:
        """A camera of horizontal field of view ``hfov_deg`` (square pixels, principal point at
        ``(width / 2, height / 2)``), for when a source does not know its intrinsics."""
        f = (width / 2.0) / math.tan(math.radians(hfov_deg) / 2.0)
        return cls(f, f, width / 2.0, height / 2.0, width, height)

    @classmethod
    def assume(cls, fov_deg: float, width: int, height: int) -> Intrinsics:
        """The lens taken for granted when a source gives no intrinsics (``falls.camera_hfov_deg``;
        docs/body-model.md "An assumed lens"), marked ``assumed``: ``fov_deg`` across the image's longer side
        (square pixels, principal point at the centre). A camera's field of view is its sensor's long side's,
        and a portrait video is that camera turned: the same lens, its long side vertical."""
        f = (max(width, height) / 2.0) / math.tan(math.radians(fov_deg) / 2.0)
        return cls(f, f, width / 2.0, height / 2.0, width, height, assumed=True)

    def scaled(self, width: int, height: int) -> Intrinsics:
        """The same camera seen at another resolution (a pure resize of the image)."""
        if (width, height) == (self.width, self.height):
            return self
        sx, sy = width / self.width, height / self.height
        return Intrinsics(self.fx * sx, self.fy * sy, (self.cx + 0.5) * sx - 0.5, (self.cy + 0.5) * sy - 0.5,
                          int(width), int(height), self.assumed)

    def deproject(self, u: np.ndarray | float, v: np.ndarray | float, z_m: np.ndarray | float) -> np.ndarray:
        """Camera-frame points (..., 3) in metres of pixels (u, v) at depth ``z_m`` (metres along z)."""
        u, v, z = np.broadcast_arrays(np.asarray(u, float), np.asarray(v, float), np.asarray(z_m, float))
        return np.stack([(u - self.cx) / self.fx * z, (v - self.cy) / self.fy * z, z], axis=-1)

    def project(self, xyz_m: np.ndarray) -> np.ndarray:
        """Pixels (..., 2) of camera-frame points (..., 3) in metres (z > 0)."""
        p = np.asarray(xyz_m, float)
        return np.stack([self.fx * p[..., 0] / p[..., 2] + self.cx, self.fy * p[..., 1] / p[..., 2] + self.cy],
                        axis=-1)

    def to_json(self, with_size: bool = True) -> dict:
        """``{"fx", "fy", "cx", "cy", "width", "height"}``; without ``width`` and ``height`` when
        ``with_size`` is False (the landmark recording's ``camera``, whose header carries ``image_size``);
        ``"assumed": true`` added for an assumed lens."""
        out: dict = {"fx": self.fx, "fy": self.fy, "cx": self.cx, "cy": self.cy}
        if with_size:
            out.update(width=self.width, height=self.height)
        if self.assumed:
            out["assumed"] = True
        return out

    @classmethod
    def from_json(cls, obj: dict, image_size: tuple[int, int] | None = None) -> Intrinsics:
        """Read :meth:`to_json`'s object. ``image_size`` gives the size when the object has no ``width`` and
        ``height`` (a landmark recording's ``camera``); raises ValueError naming what is wrong."""
        if not isinstance(obj, dict):
            raise ValueError(f"intrinsics must be a JSON object, got {obj!r}")
        for k in _FOCAL:
            v = obj.get(k)
            if not isinstance(v, (int, float)) or isinstance(v, bool):
                raise ValueError(f"intrinsics {k} must be a number, got {v!r}")
        if "width" in obj or "height" in obj or image_size is None:
            size = (obj.get("width"), obj.get("height"))
            if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in size):
                raise ValueError(f"intrinsics width and height must be integers, got {size[0]!r}, {size[1]!r}")
        else:
            size = (image_size[0], image_size[1])
        assumed = obj.get("assumed", False)
        if not isinstance(assumed, bool):
            raise ValueError(f"intrinsics assumed must be true or false, got {assumed!r}")
        return cls(*(float(obj[k]) for k in _FOCAL), size[0], size[1], assumed)
