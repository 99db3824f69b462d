"""The floor plane measured in a depth camera's images (issue 33 item 1a), for the fall detector's geometry.

Run by the landmark stage, the one that reads each frame's depth image (aligned to colour, in the ring): about
once a second of capture time (``REFRESH_S``; at once on the first depth frame and after the source started
again, and as soon as the accelerometer's gravity comes after a fit made without it), never on the other frames, the depth image is decimated to some ``TARGET_POINTS`` points and
:func:`falls.floor_plane.fit_floor` finds the floor in them, with the accelerometer's gravity as its prior when
the frame has one. It costs some 2-4 ms on the frame it runs on (``fit_ms``; docs/benchmarks.md).

The result travels with every frame that follows, as the landmark frame's ``"floor"`` field (the landmarks
topic carries it too): ``tries`` and ``misses`` (fits so far; the ones in a row since the last one that found
a floor), ``fit_ms``, ``prior`` (``imu`` or ``none``) and, while the last plane found is at most ``KEEP_S``
old: ``down`` (its unit normal, camera axes), ``height_m`` (the camera's distance to it), ``tilt_deg``,
``roll_deg``, ``inliers``, ``points``, ``fraction``, ``rms_m`` (the inliers' rms distance to it) and
``age_s`` (capture seconds since the depth image it was measured in). Carried on every frame rather than
once, so that a frame dropped on the way loses nothing. The publisher stage
(:mod:`daemon.stages.fall_watch`) hands it to the detector's camera geometry.
"""

from __future__ import annotations

import math
import time

import numpy as np

REFRESH_S = 1.0        # capture seconds between fits
KEEP_S = 30.0          # a plane older than this is no longer sent (the fall detector forgets it too)
TARGET_POINTS = 4800   # the decimated depth image's pixels (640x480 at every 8th pixel)


class DepthFloor:
    """The floor plane of a stream of depth images, refreshed every ``refresh_s`` of capture time."""

    def __init__(self, refresh_s: float = REFRESH_S, keep_s: float = KEEP_S) -> None:
        self.refresh_s = refresh_s
        self.keep_s = keep_s
        self.tries = 0
        self.misses = 0
        self.fit_ms = 0.0
        self._prior = "none"
        self._next_t: float | None = None
        self._last_t: float | None = None
        self._plane = None
        self._t_plane = 0.0

    def offer(self, depth: np.ndarray | None, depth_scale: float, intrinsics, gravity, t: float) -> bool:
        """A frame's depth image (raw units of ``depth_scale`` metres, aligned to the image ``intrinsics``
        describe at any resolution), the accelerometer's down vector (or None) and its capture time ``t``: fits
        the floor when one is due. True when it fitted (found or not)."""
        if depth is None or intrinsics is None or not depth_scale or depth.ndim != 2:
            return False
        restarted = self._last_t is not None and t < self._last_t
        self._last_t = t
        prior_came = gravity is not None and self._prior == "none"   # the accelerometer's first readings
        if self._next_t is not None and not restarted and not prior_came and t < self._next_t:
            return False
        self._next_t = t + self.refresh_s
        from posed.falls.floor_plane import fit_floor, points_from_depth

        t0 = time.perf_counter()
        h, w = depth.shape
        camera = intrinsics.scaled(w, h)
        stride = max(1, round(math.sqrt(h * w / TARGET_POINTS)))
        points = points_from_depth(depth, camera, stride, depth_scale=float(depth_scale))
        prior = None if gravity is None else np.asarray(gravity, float)
        if prior is not None and not (prior.shape == (3,) and np.all(np.isfinite(prior)) and np.any(prior)):
            prior = None
        plane = fit_floor(points, prior_down=prior, seed=self.tries)
        self.fit_ms = (time.perf_counter() - t0) * 1e3
        self.tries += 1
        self._prior = "none" if prior is None else "imu"
        if plane is None:
            self.misses += 1
        else:
            self.misses = 0
            self._plane, self._t_plane = plane, t
        return True

    def field(self, t: float) -> dict | None:
        """The frame's ``"floor"`` field at capture time ``t`` (module doc); None before the first fit."""
        if self.tries == 0:
            return None
        out: dict = {"tries": self.tries, "misses": self.misses, "fit_ms": round(self.fit_ms, 2),
                     "prior": self._prior}
        p = self._plane
        age = t - self._t_plane
        if p is not None and 0.0 <= age <= self.keep_s:
            out.update(down=[round(float(v), 6) for v in p.down], height_m=round(p.height_m, 4),
                       tilt_deg=round(p.tilt_deg, 2), roll_deg=round(p.roll_deg, 2), inliers=p.inliers,
                       points=p.points, fraction=round(p.fraction, 3), rms_m=round(p.rms_m, 4), age_s=round(age, 3))
        return out
