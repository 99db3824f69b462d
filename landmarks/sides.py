"""Left and right kept apart: BlazePose's labels flipped between two frames of one person are put back.

Seen from the side or from behind, the landmark model sometimes takes a person's left for their right for a
few frames (the whole body at once: a front view read as a back view); on pose2sim's real balancing video,
camera 2, it does so on a fifth of the frames while the man, who faces the camera throughout, only lifts a
leg. Everything downstream then sees the body turn round and back in a tenth of a second: the filters smooth
between the two labellings, the fit mirrors the skeleton, the joint angles swap sides.

A person cannot do that. Seen from the camera, a pair of points ``W`` apart across the torso (the shoulders, the
hips) shows the offset ``w = W cos(heading)`` between them, taken across the torso's long axis in the image; its
sign says which side faces the camera. Going from ``w0`` to ``w1`` takes a turn of at least
``|acos(w1/W) - acos(w0/W)|`` about that axis, and in ``dt`` seconds nobody turns by more than
:data:`TURN_RATE_MAX` ``* dt``. So when the shoulders' offset (the widest pair, and the best placed by the
model) changes sign between two frames by more turn than that, the labels flipped, and they are swapped back
(image and world landmarks together) -- unless the hips clearly kept their side (both offsets the same sign and
at least half their width: :data:`HIPS_SURE`), which a whole-body flip would not. ``W`` is the pair's true
width: the anthropometric one (Drillis and Contini: shoulders 0.259, hips 0.191 of the stature, against 0.288
from hip to shoulder) in units of the torso's length in the image -- its longest over the last
:data:`TORSO_MEMORY_S` (2 s), so that a person bending towards the camera, whose torso then looks short, is not
taken to be narrower than they are -- or the largest offset seen when that is larger. A real turn, of any speed
a person can reach, passes through the side view, where the offsets are small and the needed turn is too.

Values: :data:`TURN_RATE_MAX` 2 pi rad/s (360 deg/s): peak trunk angular velocities of turning on the spot are
about 100-250 deg/s in healthy and older adults (gait and turning studies with inertial sensors), a quick pivot
stays below 360 deg/s; above it, nothing a person at home does. :data:`MAX_GAP_S` 0.25 s: only a frame this
recent is compared (the daemon's 10 fps gives 0.1 s). Which of the two labellings is the wrong one, a frame
alone cannot say: the labels kept are those that held for :data:`SETTLED_S` (0.5 s, five frames at the daemon's
10 fps) before the flip, with the same side towards the camera -- a track's first frames, placed by the detector
rather than by tracking, are the least sure (on real video, Sports2D's demo, the model's very first frame had
the sides the other way from every later one), and a side change the test let through (the shoulders' offset
changing sign by a turn a person can make, or by a flip it could not tell from one) starts the count again --
the hips' offset, small and unsteady in the model's output, does not; a flip of labels younger than that is
taken as it comes. Labels that stay the other way for :data:`PERSIST_S` (1 s) are accepted too.

Frames: image pixels; times in seconds on the capture clock. Indices: MediaPipe Pose's 33 landmarks.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from posed.landmarks.recording import LandmarkFrame

TURN_RATE_MAX = 2.0 * math.pi     # rad/s: no person turns faster
MAX_GAP_S = 0.25                  # compare with the last frame only when it is this recent
PERSIST_S = 1.0                   # labels the other way this long are taken as they come
SETTLED_S = 0.5                   # only labels that held this long are kept against a flip
SHOULDER_WIDTH_REL = 0.90         # shoulder width / torso length (Drillis-Contini: 0.259 H / 0.288 H)
HIP_WIDTH_REL = 0.66              # hip width / torso length (0.191 H / 0.288 H)
HIPS_SURE = 0.5                   # hips this far apart (of their width) that keep their side veto a flip
TORSO_MEMORY_S = 2.0              # the torso's longest image length over this long is its unforeshortened one

# MediaPipe Pose index of each landmark's left/right counterpart (the nose is its own)
MIRROR = np.array([0, 4, 5, 6, 1, 2, 3, 8, 7, 10, 9] + [i + 1 if i % 2 else i - 1 for i in range(11, 33)])
TORSO = np.array([11, 12, 23, 24])   # left shoulder, right shoulder, left hip, right hip


def torso_length(xy: np.ndarray) -> float:
    """Distance from the mid-hip to the mid-shoulder, pixels (``xy``: the 33 landmarks' x, y)."""
    return float(np.linalg.norm(torso_axis(xy)))


def torso_axis(xy: np.ndarray) -> np.ndarray:
    """The mid-hip → mid-shoulder vector, pixels (``xy``: the 33 landmarks' x, y)."""
    return 0.5 * (xy[11] + xy[12]) - 0.5 * (xy[23] + xy[24])


def signed_widths(xy: np.ndarray, axis: np.ndarray | None = None) -> np.ndarray:
    """(shoulders, hips): the left point's offset from the right one across the torso (along the normal of
    ``axis``, by default the frame's own mid-hip → mid-shoulder axis), pixels; the sign says which side faces
    the camera."""
    axis = torso_axis(xy) if axis is None else axis
    normal = np.array([-axis[1], axis[0]]) / max(float(np.linalg.norm(axis)), 1e-9)
    return np.array([float((xy[11] - xy[12]) @ normal), float((xy[23] - xy[24]) @ normal)])


def pair_widths(now: np.ndarray, before: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(before's, now's) :func:`signed_widths`, both across one axis: that of the frame whose torso is the
    longer in the image. Between two frames a tenth of a second apart the torso's image axis cannot turn
    round in the image plane (a half turn in 0.1 s is 1800 deg/s); it reverses only when the torso pitches
    through the line of sight (bending towards or away from a camera above or below it), where the shorter
    torso's own axis is noise and, past end-on, points the other way -- which would flip the sign of the
    offsets with no turn and no label swapped. The axis is the same for either labelling (the midpoints do
    not depend on it), so a real flip still shows."""
    axis = torso_axis(before) if torso_length(before) >= torso_length(now) else torso_axis(now)
    return signed_widths(before, axis), signed_widths(now, axis)


def turn_needed(w_before: float, w_now: float, width: float) -> float:
    """The least turn (radians) of a pair of points ``width`` apart about the torso's long axis that takes
    their projected offset from ``w_before`` to ``w_now`` (offset = width · cos(heading))."""
    width = max(width, abs(w_before), abs(w_now), 1e-9)
    return abs(math.acos(w_now / width) - math.acos(w_before / width))


def labels_flipped(now: np.ndarray, before: np.ndarray, dt: float, torso_px: float = 0.0) -> bool:
    """Whether the torso landmarks ``now`` (33, ≥2 pixels) have left and right the other way from ``before``,
    ``dt`` seconds earlier, by more turn than :data:`TURN_RATE_MAX` allows (see the module doc). ``torso_px``:
    the torso's length in the image when it is not foreshortened, if known (else the two frames' own)."""
    a, b = now[:, :2].astype(np.float64), before[:, :2].astype(np.float64)
    if not (np.isfinite(a[TORSO]).all() and np.isfinite(b[TORSO]).all()) or dt <= 0.0:
        return False
    size = max(0.5 * (torso_length(a) + torso_length(b)), torso_px)
    if not size > 0.0:
        return False
    (sh0, hip0), (sh1, hip1) = pair_widths(a, b)
    if not (sh0 * sh1 < 0.0 and turn_needed(sh0, sh1, SHOULDER_WIDTH_REL * size) > TURN_RATE_MAX * dt):
        return False
    hips_kept = hip0 * hip1 > 0.0 and min(abs(hip0), abs(hip1)) >= HIPS_SURE * HIP_WIDTH_REL * size
    return not hips_kept


class SideKeeper:
    """One person's left/right labels across frames: :meth:`check` each frame's raw landmarks, in order."""

    def __init__(self) -> None:
        self._last: np.ndarray | None = None
        self._last_t = 0.0
        self._flipped_since: float | None = None
        self._settled_since = 0.0        # when the labels now kept started to hold
        self._lengths: list[tuple[float, float]] = []   # (t, torso length px) of the last TORSO_MEMORY_S

    def reset(self) -> None:
        self._last = None
        self._flipped_since = None
        self._lengths.clear()

    def check(self, t: float, landmarks: np.ndarray, world: np.ndarray | None
              ) -> tuple[np.ndarray, np.ndarray | None, bool]:
        """``(landmarks, world, swapped)``: the frame's image landmarks (33, 5) and world landmarks (33, k, or
        None without them) at ``t`` seconds, left and right swapped back when the labels flipped since the last
        frame checked."""
        swapped = False
        length = torso_length(landmarks[:, :2])
        if math.isfinite(length):
            self._lengths = [(tl, v) for tl, v in self._lengths if t - tl <= TORSO_MEMORY_S] + [(t, length)]
        torso_px = max((v for _, v in self._lengths), default=0.0)
        if self._last is None or not 0.0 < t - self._last_t <= MAX_GAP_S:
            self._settled_since, self._flipped_since = t, None
        elif labels_flipped(landmarks, self._last, t - self._last_t, torso_px):
            if self._flipped_since is None:
                self._flipped_since = t
            if self._flipped_since - self._settled_since >= SETTLED_S and t - self._flipped_since <= PERSIST_S:
                landmarks, world, swapped = landmarks[MIRROR], None if world is None else world[MIRROR], True
            else:                                   # the model's labels are taken: they start to settle now
                self._settled_since, self._flipped_since = t, None
        else:
            self._flipped_since = None
            before, now = pair_widths(landmarks[:, :2], self._last)
            if before[0] * now[0] < 0.0:
                self._settled_since = t             # a turn a person can make, or a flip the test cannot tell
        self._last, self._last_t = landmarks[:, :2].copy(), t
        return landmarks, world, swapped


class RecordingSides:
    """Left and right of a recording whose extractor did not keep them (another tool's, or one whose header
    lacks ``sides_kept``), checked as the landmark stage checks its own: one :class:`SideKeeper` per person
    (``people``' track ids; the frame's own person otherwise), image and world landmarks and the depth at them
    swapped back together. What ``posed fit``, ``posed falls`` and the daemon's recording replay do to each
    frame they fit, in capture order. ``frames_put_back`` counts the frames where any person's labels were."""

    def __init__(self) -> None:
        self._own = SideKeeper()
        self._people: dict[int, tuple[SideKeeper, float]] = {}    # track id -> (keeper, when last seen)
        self.frames_put_back = 0

    @staticmethod
    def needed(header, enabled: bool) -> bool:
        """Whether a recording with ``header`` (a :class:`RecordingHeader`) is checked: ``enabled`` (the
        config's ``landmarks.keep_sides``) and its extractor did not say it kept them already."""
        return enabled and header.extra.get("sides_kept") is not True

    def __call__(self, frame: LandmarkFrame) -> LandmarkFrame:
        """``frame`` with every person's labels put back where they flipped since the last frame checked."""
        if frame.landmarks is None and not frame.people:
            self._own.reset()          # nobody in view: the next person's labels start afresh
            return frame
        if not frame.people:
            landmarks, world, swapped = self._own.check(frame.t, frame.landmarks, frame.world)
            if not swapped:
                return frame
            self.frames_put_back += 1
            return replace(frame, landmarks=landmarks, world=world, depth_m=_mirrored(frame.depth_m, swapped))
        # a track unseen for longer than a comparison reaches is forgotten (a long replay meets many ids)
        self._people = {i: kt for i, kt in self._people.items() if frame.t - kt[1] <= MAX_GAP_S}
        people, own, any_swapped = [], None, False
        for p in frame.people:
            keeper = self._people.get(p.id, (SideKeeper(), frame.t))[0]
            self._people[p.id] = (keeper, frame.t)
            landmarks, world, swapped = keeper.check(frame.t, p.landmarks, p.world)
            people.append(replace(p, landmarks=landmarks, world=world, depth_m=_mirrored(p.depth_m, swapped))
                          if swapped else p)
            if frame.landmarks is not None and np.array_equal(p.landmarks, frame.landmarks, equal_nan=True):
                own = (landmarks, _mirrored(frame.world, swapped), _mirrored(frame.depth_m, swapped))
            any_swapped |= swapped
        if not any_swapped:
            return frame
        self.frames_put_back += 1
        if own is None:
            return replace(frame, people=tuple(people))
        return replace(frame, people=tuple(people), landmarks=own[0], world=own[1], depth_m=own[2])


def _mirrored(values: np.ndarray | None, swapped: bool) -> np.ndarray | None:
    """Per-landmark ``values`` (world landmarks, depths; None when unknown) with left and right swapped when
    ``swapped``."""
    return values[MIRROR] if swapped and values is not None else values
