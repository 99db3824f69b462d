"""One person hidden behind another in the synthetic scenes: which landmarks, and what the landmark stage says.

The synthetic renderer (:mod:`bench.falls_body`) draws every body whole. In a room, a bystander between the
camera and the person they help covers part of that person, and the landmark model still answers for the
covered landmarks.

**Which landmarks are hidden.** The other person's body is a set of capsules around their skeleton's
segments. The radii come from the renderer's own contact spheres (``FLOOR_CONTACTS``, fractions of body
height H): thigh 0.04 H, shank 0.03 H, upper arm 0.03 H, forearm 0.022 H, trunk 0.065 H, across the
shoulders 0.04 H and the hips 0.055 H, head 0.06 H; the neck 0.035 H (a neck about 38 cm round on a 1.75 m
adult). A landmark is hidden when the ray from the camera centre to it passes through a capsule in front of
it. Both ends are in camera axes, metres.

**What the landmark stage says for them.** Measured, not assumed: posed's landmark stage (BlazePose full)
was run on the composited two-person crossings of ``posed bench people --part scenes`` (real footage, one
person walking in front of or behind another). For every landmark that the other person's pixels cover, the
error of the two-person run was measured against the person's truth (development views cam01, cam02 and
cam04, 24 random crossings each, seed 0; 2026-12-06, docs/benchmarks.md, "A bystander who covers the person
who fell"):

* **Error.** As a fraction of the person's size (the square root of their landmark box's area), the quantiles
  are in ``ERROR_QUANTILES``: median 0.109, 90th percentile 0.521. Alone, the same landmarks are off by a
  median 0.014. The landmark is not lost: the model puts it somewhere else, often far.
* **Direction.** No preferred one. Its component towards the other person's centre has median -0.005 of the
  size and mean -0.03 of the error's length.
* **Time.** Lasting: the error's size at one frame and 0.2 s later correlates at 0.70 (``LAG_CORRELATION``).
* **Visibility.** Still high: median 0.978, 10th percentile 0.724 (``VISIBILITY_QUANTILES``). The model
  does not know the landmark is covered, so neither do the fit and the fall detector.
* **Found at all.** Of the frames where a person was found alone, the share the two-person run found them on,
  by the share of their landmarks covered (none / under 10 % / 10-40 % / 40 % or more; 8,808 person-frames):
  0.85 / 0.83 / 0.61 / 0.25 over both people; the woman, followed from the start and standing in place,
  1.00 / 0.95 / 0.84 / 0.65; the man, walking in, 0.68 / 0.40 / 0.28 / 0.05.

The reported view, cam03, was measured after the table was set, as a check (1,302 hidden landmarks): median
0.094, 90th percentile 0.327, visibility median 0.991, lag correlation 0.58. Its tail is lighter; the
model keeps the development views' heavier one.

So a person with ``LOST_SHARE`` (40 %) or more of their landmarks covered is not found, a worst case (the
measured rate there is 0.25). Otherwise each covered landmark is moved by a 2D offset. The offset follows a
first-order autoregression in time, with that correlation, and its size is drawn from the measured quantiles
when the landmark becomes hidden (seeded per person). Its visibility is drawn from the measured quantiles
each frame.

Not modelled: a landmark pass whose region slides from the hidden person onto the one in front. That is the
real crossings' identity failure (docs/benchmarks.md, "Several people"). Here identities come from the
landmarks each person is given.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from posed.bench.falls_body import MP, Body, WorldCamera

# (from, to, radius as a fraction of body height): the occluding body
CAPSULES = (
    ("left_hip", "left_knee", 0.04), ("right_hip", "right_knee", 0.04),
    ("left_knee", "left_ankle", 0.03), ("right_knee", "right_ankle", 0.03),
    ("left_heel", "left_foot_index", 0.02), ("right_heel", "right_foot_index", 0.02),
    ("left_shoulder", "left_elbow", 0.03), ("right_shoulder", "right_elbow", 0.03),
    ("left_elbow", "left_wrist", 0.022), ("right_elbow", "right_wrist", 0.022),
    ("left_shoulder", "left_hip", 0.065), ("right_shoulder", "right_hip", 0.065), ("chest", "pelvis", 0.065),
    ("left_shoulder", "right_shoulder", 0.04), ("left_hip", "right_hip", 0.055),
    ("chest", "head", 0.035), ("head", "head", 0.06),
)
# measured quantiles (development views, 2,902 hidden landmarks on 542 person-frames): minimum, 10th ... 99th
LEVELS = (0.0, 0.1, 0.25, 0.5, 0.75, 0.9, 0.95, 0.99)
ERROR_QUANTILES = (0.003, 0.024, 0.045, 0.109, 0.280, 0.521, 0.631, 0.784)   # fractions of the person's size
VISIBILITY_QUANTILES = (0.325, 0.724, 0.865, 0.978, 0.999, 1.0, 1.0, 1.0)
LAG_CORRELATION = 0.70        # of the hidden landmark's error, over LAG_S
LAG_S = 0.2
LOST_SHARE = 0.4              # this share of a person's landmarks covered or more: not found


def _segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For rays 0 -> p (n, 3) and one segment a -> b (3,): the least distance between them (n,) and where it is
    along each ray (n,; 0 the camera, 1 the landmark)."""
    d1, d2 = p, b - a
    r = -a
    a11 = np.einsum("ij,ij->i", d1, d1)
    a22 = float(d2 @ d2)
    a12 = d1 @ d2
    b1 = d1 @ r
    b2 = float(d2 @ r)
    if a22 < 1e-12:              # a sphere: the closest point of each ray to a
        s = np.clip(-b1 / a11, 0.0, 1.0)
        t = np.zeros_like(s)
    else:
        den = a11 * a22 - a12 * a12
        s = np.where(den > 1e-12, (a12 * b2 - a22 * b1) / np.maximum(den, 1e-12), 0.0)
        s = np.clip(s, 0.0, 1.0)
        t = np.clip((a12 * s + b2) / a22, 0.0, 1.0)
        s = np.clip((a12 * t - b1) / a11, 0.0, 1.0)   # the ray's point nearest the clamped segment point
    gap = d1 * s[:, None] - (a + d2 * t[:, None])
    return np.linalg.norm(gap, axis=1), s


def hidden(points_cam: np.ndarray, other_cam: dict[str, np.ndarray], other_height: float) -> np.ndarray:
    """Which of ``points_cam`` (33, 3: one person's landmarks, camera axes, m) the other person's body
    (``other_cam``: joint name -> camera-axes point, m; ``other_height`` m) covers: (33,) bool."""
    out = np.zeros(len(points_cam), bool)
    length = np.linalg.norm(points_cam, axis=1)
    for j0, j1, frac in CAPSULES:
        radius = frac * other_height
        dist, s = _segment_distance(points_cam, other_cam[j0], other_cam[j1])
        out |= (dist < radius) & (s * length < length - radius)
    return out


def _inverse_cdf(u: float, values: tuple[float, ...]) -> float:
    return float(np.interp(u, LEVELS, values))


@dataclass
class Occluder:
    """What the landmark stage says of one person's hidden landmarks, frame after frame (module doc); seeded."""

    seed: int
    offsets: dict[int, np.ndarray] = field(default_factory=dict)    # landmark -> offset, fractions of size
    scale: dict[int, float] = field(default_factory=dict)
    rng: np.random.Generator = field(init=False)

    def __post_init__(self) -> None:
        self.rng = np.random.default_rng(self.seed)

    def apply(self, landmarks: np.ndarray, covered: np.ndarray, size_px: float, dt: float) -> np.ndarray | None:
        """``landmarks`` (33, 5) with the ``covered`` ones moved and their visibility redrawn, or None (the person
        not found) when at least ``LOST_SHARE`` of them are covered; ``size_px`` the person's size in the
        image, ``dt`` s since the previous frame."""
        if covered.mean() >= LOST_SHARE:
            return None
        out = landmarks.copy()
        rho = LAG_CORRELATION ** (max(dt, 0.0) / LAG_S)
        for j in range(len(covered)):
            if not covered[j]:
                self.offsets.pop(j, None)
                self.scale.pop(j, None)
                continue
            if j not in self.offsets:       # newly hidden: its error's size, in any direction
                m = _inverse_cdf(float(self.rng.random()), ERROR_QUANTILES)
                angle = self.rng.uniform(0.0, 2.0 * math.pi)
                self.scale[j] = m
                self.offsets[j] = m * np.array([math.cos(angle), math.sin(angle)])
            else:
                step = self.rng.normal(0.0, self.scale[j] / math.sqrt(2.0), 2)
                self.offsets[j] = rho * self.offsets[j] + math.sqrt(1.0 - rho * rho) * step
            out[j, :2] = landmarks[j, :2] + self.offsets[j] * size_px
            out[j, 3] = _inverse_cdf(float(self.rng.random()), VISIBILITY_QUANTILES)
        return out


def body_points(joints_world: dict[str, np.ndarray], camera: WorldCamera) -> dict[str, np.ndarray]:
    """A rendered body's joints in camera axes (m), by name."""
    return {name: camera.to_camera(p) for name, p in joints_world.items()}


def landmark_points(points_cam: dict[str, np.ndarray]) -> np.ndarray:
    """The 33 landmark points (MediaPipe order) of a body's :func:`body_points`, (33, 3)."""
    return np.array([points_cam[name] for name in MP])


def size_px(joints_world: dict[str, np.ndarray], camera: WorldCamera, body: Body) -> float:
    """The person's size in the image: the square root of their noise-free landmark box's area (px), as the
    hidden-landmark error was measured against."""
    lm = camera.project(joints_world, body)
    if lm is None:
        return 1.0
    w, h = np.ptp(lm[:, 0]), np.ptp(lm[:, 1])
    return float(math.sqrt(max(w, 1.0) * max(h, 1.0)))
