"""Temporal filters of MediaPipe's ``PoseLandmarkFiltering`` graph (tech-notes d.10), vectorized.

* :class:`LowPass`: ``y = alpha·x + (1 − alpha)·y_prev``, the first sample passes through (``LowPassFilter``).
* :class:`OneEuro`: MediaPipe's ``OneEuroFilter`` on every element of an array: the sampling frequency starts
  at 30 Hz and is then ``1/Δt`` of consecutive timestamps; ``dx = (x − x_prev_raw)·value_scale·freq`` (0 on
  the first sample), ``edx = LPF(dx, alpha(derivate_cutoff))``, cutoff ``fc = min_cutoff + beta·|edx|``,
  ``x̂ = LPF(x, alpha(fc))`` with ``alpha(fc) = 1/(1 + τ/Te)``, ``τ = 1/(2π·fc)``, ``Te = 1/freq``. A timestamp
  that does not increase returns the input unfiltered and leaves the state alone.
* :class:`PoseSmoother`: the three streams with MediaPipe's current parameters; coordinates are filtered in
  image pixels (z on the x scale), the value scale is ``1/object_scale`` with object_scale the side of the
  alignment rectangle of the *unfiltered* auxiliary landmarks (2·|aux34 − aux33|, pixels, no 1.25 factor).

Timestamps are seconds (the frame's capture time). MediaPipe uses 0 as "no previous timestamp"; here the
first sample is marked explicitly, so a recording that starts at t = 0 is filtered from its second frame on.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from posed.landmarks.roi import alignment_size
from posed.landmarks.sides import SideKeeper

DEFAULT_FREQUENCY = 30.0
MIN_OBJECT_SCALE = 1e-6


class LowPass:
    """Exponential low-pass filter on an array; ``alpha`` is the weight of the new sample."""

    def __init__(self, alpha: float) -> None:
        if not 0.0 <= alpha <= 1.0:
            raise ValueError(f"alpha must be in [0, 1], got {alpha}")
        self.alpha = alpha
        self.raw: np.ndarray | None = None
        self.value: np.ndarray | None = None

    def reset(self) -> None:
        self.raw = None
        self.value = None

    def apply(self, x: np.ndarray, alpha: float | np.ndarray | None = None) -> np.ndarray:
        a = self.alpha if alpha is None else alpha
        x = np.array(x, dtype=np.float64)
        y = x if self.value is None else a * x + (1.0 - a) * self.value
        self.raw = x
        self.value = y
        return y.copy()


@dataclass(frozen=True)
class OneEuroParams:
    min_cutoff: float
    beta: float
    derivate_cutoff: float = 1.0
    value_scaling: bool = True


# MediaPipe pose_landmark_filtering.pbtxt (since 2021-06).
LANDMARK_PARAMS = OneEuroParams(min_cutoff=0.05, beta=80.0)
WORLD_PARAMS = OneEuroParams(min_cutoff=0.1, beta=40.0, value_scaling=False)
AUX_PARAMS = OneEuroParams(min_cutoff=0.01, beta=10.0)
VISIBILITY_ALPHA = 0.1


def _alpha(cutoff: float | np.ndarray, frequency: float) -> float | np.ndarray:
    te = 1.0 / frequency
    tau = 1.0 / (2.0 * math.pi * cutoff)
    return 1.0 / (1.0 + tau / te)


class OneEuro:
    """One-euro filter applied element-wise to arrays of a fixed shape."""

    def __init__(self, params: OneEuroParams, frequency: float = DEFAULT_FREQUENCY) -> None:
        self.params = params
        self.initial_frequency = frequency
        self.reset()

    def reset(self) -> None:
        self.frequency = self.initial_frequency
        self.last_t: float | None = None
        self._x = LowPass(1.0)
        self._dx = LowPass(1.0)

    def apply(self, t: float, x: np.ndarray, value_scale: float = 1.0) -> np.ndarray:
        x = np.asarray(x, dtype=np.float64)
        if self.last_t is not None:
            if t <= self.last_t:
                return x.copy()
            self.frequency = 1.0 / (t - self.last_t)
        self.last_t = t
        p = self.params
        dx = np.zeros_like(x) if self._x.raw is None else (x - self._x.raw) * value_scale * self.frequency
        edx = self._dx.apply(dx, _alpha(p.derivate_cutoff, self.frequency))
        cutoff = p.min_cutoff + p.beta * np.abs(edx)
        return self._x.apply(x, _alpha(cutoff, self.frequency))


class PoseSmoother:
    """Smooths image landmarks, auxiliary landmarks and world landmarks of consecutive frames.

    ``apply`` takes the unfiltered (33, 5) image landmarks in pixels, the (2, 5) auxiliary landmarks and the
    (33, 3) world landmarks, and returns the three filtered arrays and the world landmarks' visibility, which
    is the image landmarks' (MediaPipe filters the same values twice, in two calculators). ``smooth_landmarks=False`` leaves the image and world landmarks alone (MediaPipe's
    ``smooth_landmarks``); the auxiliary landmarks, which steer the next ROI, are always filtered.
    """

    def __init__(self, smooth_landmarks: bool = True) -> None:
        self.smooth_landmarks = smooth_landmarks
        self.visibility = LowPass(VISIBILITY_ALPHA)
        self.landmarks = OneEuro(LANDMARK_PARAMS)
        self.world = OneEuro(WORLD_PARAMS)
        self.aux_visibility = LowPass(VISIBILITY_ALPHA)
        self.aux = OneEuro(AUX_PARAMS)
        self.sides = SideKeeper()       # the person's left/right labels (landmarks.sides), checked before filtering

    def reset(self) -> None:
        for f in (self.visibility, self.landmarks, self.world, self.aux_visibility, self.aux, self.sides):
            f.reset()

    def apply(self, t: float, landmarks: np.ndarray, aux: np.ndarray,
              world: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Returns ``(landmarks (33, 5), aux (2, 5), world (33, 3), world_visibility (33,))`` filtered."""
        object_scale = alignment_size(aux[0, :2], aux[1, :2])
        scaled = object_scale >= MIN_OBJECT_SCALE
        value_scale = 1.0 / object_scale if scaled else 1.0

        aux_out = aux.copy()
        aux_out[:, 3] = self.aux_visibility.apply(aux[:, 3])
        if scaled:
            aux_out[:, :3] = self.aux.apply(t, aux[:, :3], value_scale)

        if not self.smooth_landmarks:
            return landmarks.copy(), aux_out, world.copy(), np.array(landmarks[:, 3], dtype=np.float64)

        out = landmarks.copy()
        out[:, 3] = self.visibility.apply(landmarks[:, 3])
        if scaled:
            out[:, :3] = self.landmarks.apply(t, landmarks[:, :3], value_scale)
        world_out = self.world.apply(t, world, 1.0)
        return out, aux_out, world_out, out[:, 3].copy()
