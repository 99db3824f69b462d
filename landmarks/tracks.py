"""Who is who across frames: :class:`PersonTracker` gives every person a track id (pure numpy, no images).

Each frame the landmark stage hands over the people it found (33 landmarks each, image pixels) and, when it
has one, the landmark *slot* that followed each of them (the per-person ROI tracker of
:class:`~landmarks.people.MultiPoseLandmarker`). The tracker matches them to its tracks by

* **box overlap**: IoU of the person's landmark box with the track's box moved by its velocity;
* **landmark overlap**: an OKS-like score, the mean over the landmarks visible in both of
  ``exp(-d² / (2 (KAPPA·s)²))`` with ``d`` the distance to the track's landmarks moved by its velocity and ``s``
  the track's size (square root of its box area), ``s`` growing while the track is lost (it may have walked);
* **motion**: the velocity (box centre, pixels/s, smoothed) that both predictions above use;
* **body proportions** (for a track that was lost): the lengths of 10 body segments relative to the torso,
  learned while the track is seen; a re-found person must have about the same proportions;
* **slot continuity**: the same slot as in the last frame adds ``slot_bonus`` (the landmark model followed
  that body from one frame to the next, the strongest evidence there is).

Similarity = ``w_box·IoU + w_landmarks·OKS`` (+ slot bonus), times the proportions' agreement for a lost track;
pairs below ``min_similarity`` never match, the rest are matched greedily, best pair first (a handful of
people: greedy equals the optimal assignment but for near ties). An unmatched person gets a new id (ids count
up from 1 and are never reused); a track not seen for more than ``lost_keep_s`` (default 2 s) is forgotten, so a
person who leaves and comes back within 2 s, near where they were lost (and as they were going), gets their id
back, later a new one.

**Hidden behind someone.** A track lost where its last box overlaps the box of someone seen in the same frame
was most likely walked behind (or in front of) them: the person is still in the room, out of sight only while
the other covers them. Such a track remembers who covers it and is kept for up to ``hidden_keep_s`` while that
person is still followed. It is looked for anywhere along its way, from where it was lost to where its
velocity would have taken it by now (they may have stopped behind the other, or walked on and out the far
side). That velocity is the one last measured while the track's box touched nobody's: as a person goes behind
someone, their visible landmarks shrink towards one side and the box centre's motion stops being theirs. Its
prediction is the point of that segment nearest the candidate, with the falloff widened for the time gone as
for any lost track, and the proportions must agree, on the segments clear of the covering person's box only
(grown by ``COVERED_ERROR`` of the track's size): as they come out, the landmarks still behind that person are
the model's guesses, off by a median 0.11 of the person's size and by more than ``COVERED_ERROR`` on one
frame in four (measured on real crossings), and say nothing of the body. Hidden tracks are matched last, to
the people no other track took: their way runs right behind the person covering them, who is their own
track's. A person lost where nobody covers them (out of the image, through a door) keeps the ``lost_keep_s``
rule.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from posed.landmarks.sides import MIRROR

KAPPA = 0.1                 # OKS falloff, as a fraction of the person's size
VISIBLE = 0.5               # a landmark counts as seen above this visibility
SEGMENTS = ((11, 12), (23, 24), (11, 13), (13, 15), (12, 14), (14, 16), (23, 25), (25, 27), (24, 26), (26, 28))
TORSO = ((11, 12), (23, 24))  # mid-shoulder to mid-hip from these pairs' midpoints
COVERED_ERROR = 0.28        # a covered landmark is put within this share of the person's size of where it is,
                            # on 3 frames of 4 (measured: bench/people_occlusion.py, ERROR_QUANTILES' 75th)


@dataclass(frozen=True)
class TrackerConfig:
    """Matching weights and limits (see the module doc)."""

    lost_keep_s: float = 2.0          # a track not seen for longer is forgotten (its id is never reused)
    min_similarity: float = 0.2       # pairs below never match
    w_box: float = 0.4
    w_landmarks: float = 0.6
    slot_bonus: float = 0.5
    lost_after_s: float = 0.25        # a track unseen this long counts as lost: proportions are checked
    size_ratio_max: float = 2.0       # a person cannot change size by more than this between matches
    max_extrapolate_s: float = 0.5    # the velocity moves a prediction at most this far ahead
    hidden_keep_s: float = 5.0        # a track lost behind someone still followed is kept this long (as long as
                                      # the fall stage keeps an unseen person: falls.people.FORGET_S)


@dataclass(frozen=True)
class TrackInfo:
    """A track as the tracker knows it now: ``id``, ``first_t`` and ``last_t`` (seconds, first and last seen),
    ``hits`` (frames matched), ``box`` (4,) xmin, ymin, xmax, ymax pixels, ``velocity`` (2,) pixels/s."""

    id: int
    first_t: float
    last_t: float
    hits: int
    box: np.ndarray
    velocity: np.ndarray


def visible_mask(lms: np.ndarray) -> np.ndarray:
    """Landmarks with coordinates and visibility above VISIBLE; all with coordinates when fewer than 4 are."""
    finite = np.isfinite(lms[:, :2]).all(axis=1)
    if lms.shape[1] < 4:
        return finite
    vis = finite & (np.nan_to_num(lms[:, 3]) > VISIBLE)
    return vis if vis.sum() >= 4 else finite


def landmark_box(lms: np.ndarray) -> np.ndarray:
    """xmin, ymin, xmax, ymax of the visible landmarks (pixels)."""
    pts = lms[visible_mask(lms), :2]
    if pts.size == 0:
        return np.full(4, np.nan)
    return np.concatenate([pts.min(axis=0), pts.max(axis=0)])


def box_size(box: np.ndarray) -> float:
    """sqrt of the box's area, at least 1 pixel."""
    return float(max(np.sqrt(max(box[2] - box[0], 0.0) * max(box[3] - box[1], 0.0)), 1.0))


def _centre(box: np.ndarray) -> np.ndarray:
    """(2,) centre of a box xmin, ymin, xmax, ymax."""
    return (box[:2] + box[2:]) / 2


def _intersection(a: np.ndarray, b: np.ndarray) -> float:
    """Area (pixels²) shared by two boxes xmin, ymin, xmax, ymax."""
    ix = min(a[2], b[2]) - max(a[0], b[0])
    iy = min(a[3], b[3]) - max(a[1], b[1])
    return float(ix * iy) if ix > 0 and iy > 0 else 0.0


def box_iou(a: np.ndarray, b: np.ndarray) -> float:
    inter = _intersection(a, b)
    if inter == 0.0:
        return 0.0
    union = (a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter
    return float(inter / union) if union > 0 else 0.0


def oks(a: np.ndarray, b: np.ndarray, size: float, kappa: float = KAPPA) -> float:
    """Landmark overlap of two (33, ≥2) sets in [0, 1]: mean ``exp(-d²/(2 (kappa·size)²))`` over the landmarks
    visible in both (all with coordinates in both when fewer than 4 are)."""
    both = visible_mask(a) & visible_mask(b)
    if both.sum() < 4:
        both = np.isfinite(a[:, :2]).all(axis=1) & np.isfinite(b[:, :2]).all(axis=1)
    if not both.any():
        return 0.0
    d2 = ((a[both, :2] - b[both, :2]) ** 2).sum(axis=1)
    return float(np.exp(-d2 / (2.0 * (kappa * size) ** 2)).mean())


def body_overlap(a: np.ndarray, b: np.ndarray, size: float | None = None) -> float:
    """How much two landmark sets look like the same body: the larger :func:`oks` of ``b`` as it is and with
    left and right swapped (a model that saw the person from the wrong side); ``size`` defaults to the
    smaller of their box sizes."""
    if size is None:
        size = min(box_size(landmark_box(a)), box_size(landmark_box(b)))
    return max(oks(a, b, size), oks(a, b[MIRROR], size))


def proportions(lms: np.ndarray, unseen: np.ndarray | None = None) -> np.ndarray:
    """Lengths of the 10 SEGMENTS over the torso length (NaN where a landmark is not visible, or inside the
    box ``unseen``: xmin, ymin, xmax, ymax pixels)."""
    vis = visible_mask(lms)
    if unseen is not None:
        vis = vis & ~((lms[:, 0] >= unseen[0]) & (lms[:, 0] <= unseen[2]) & (lms[:, 1] >= unseen[1])
                      & (lms[:, 1] <= unseen[3]))
    xy = np.where(vis[:, None], lms[:, :2], np.nan)
    mid_sh = (xy[11] + xy[12]) / 2
    mid_hp = (xy[23] + xy[24]) / 2
    torso = float(np.hypot(*(mid_sh - mid_hp)))
    if not torso > 1.0:
        return np.full(len(SEGMENTS), np.nan)
    return np.array([np.hypot(*(xy[i] - xy[j])) for i, j in SEGMENTS]) / torso


def proportion_agreement(a: np.ndarray, b: np.ndarray) -> float:
    """1 for the same proportions, falling with the median |log ratio| of the segments known in both (0.25 →
    about 0.37); 1 when fewer than 3 segments are known in both (no evidence either way)."""
    ok = np.isfinite(a) & np.isfinite(b) & (a > 0) & (b > 0)
    if ok.sum() < 3:
        return 1.0
    return float(np.exp(-np.median(np.abs(np.log(a[ok] / b[ok]))) / 0.25))


class _Track:
    __slots__ = ("id", "first_t", "last_t", "hits", "lms", "box", "velocity", "free_velocity", "props", "slot",
                 "behind")

    def __init__(self, tid: int, t: float, lms: np.ndarray, slot: int | None) -> None:
        self.id, self.first_t, self.last_t, self.hits = tid, t, t, 1
        self.lms = lms.copy()
        self.box = landmark_box(lms)
        self.velocity = np.zeros(2)
        self.free_velocity = np.zeros(2)   # the velocity as last measured while the box touched nobody's
        self.props = proportions(lms)
        self.slot = slot
        self.behind: int | None = None     # id of the person whose box covered this track's when it was lost

    def info(self) -> TrackInfo:
        return TrackInfo(self.id, self.first_t, self.last_t, self.hits, self.box.copy(), self.velocity.copy())


class PersonTracker:
    """Track ids for the people of successive frames (see the module doc). Not thread-safe."""

    def __init__(self, config: TrackerConfig | None = None) -> None:
        self.config = config if config is not None else TrackerConfig()
        self._tracks: list[_Track] = []
        self._next_id = 1
        self._last_t: float | None = None

    def reset(self) -> None:
        """Forget every track (ids keep counting up)."""
        self._tracks = []
        self._last_t = None

    @property
    def tracks(self) -> list[TrackInfo]:
        """The tracks kept now (seen, lost for at most ``lost_keep_s`` or hidden behind someone still followed for
        at most ``hidden_keep_s``), oldest first."""
        return [tr.info() for tr in self._tracks]

    def first_seen(self, track_id: int) -> float:
        """When the track was first seen (seconds); ``inf`` for an unknown id."""
        return next((tr.first_t for tr in self._tracks if tr.id == track_id), float("inf"))

    def longest_followed(self, ids: list[int]) -> int | None:
        """Of ``ids``, the one followed longest (first seen earliest; the smaller id on a tie), or None."""
        return min(ids, key=lambda i: (self.first_seen(i), i)) if ids else None

    def similarity(self, track: _Track, lms: np.ndarray, box: np.ndarray, slot: int | None, t: float) -> float:
        """How well a person (landmarks ``lms``, their ``box``, found by ``slot``) continues ``track`` at ``t``."""
        cfg = self.config
        if not np.isfinite(box).all():
            return 0.0
        dt = max(t - track.last_t, 0.0)
        if track.behind is not None:          # hidden: anywhere from where it was lost to where it was going
            shift = _nearest_on_way(track.free_velocity * dt, _centre(box) - _centre(track.box))
        else:
            shift = track.velocity * min(dt, cfg.max_extrapolate_s)
        size_t, size_o = box_size(track.box), box_size(box)
        if not (1.0 / cfg.size_ratio_max <= size_o / size_t <= cfg.size_ratio_max):
            return 0.0
        lost = dt > cfg.lost_after_s
        # a lost track's position is less certain the longer it is gone: widen the landmark falloff
        size = size_t * (1.0 + (dt / cfg.lost_after_s - 1.0 if lost else 0.0) * 0.5)
        pred = track.lms.copy()
        pred[:, :2] += shift
        pred_box = track.box + np.tile(shift, 2)
        sim = cfg.w_box * box_iou(pred_box, box) + cfg.w_landmarks * oks(pred, lms, size)
        if lost:
            sim *= proportion_agreement(track.props, proportions(lms, self._cover(track)))
        elif slot is not None and slot == track.slot and track.last_t == self._last_t:
            sim += cfg.slot_bonus
        return sim

    def _cover(self, track: _Track) -> np.ndarray | None:
        """Where a hidden track's landmarks may still be covered: the box of the person covering it, grown by
        ``COVERED_ERROR`` of the track's size on each side (None for a track nobody covers)."""
        if track.behind is None:
            return None
        other = next((o for o in self._tracks if o.id == track.behind), None)
        if other is None:
            return None
        grow = COVERED_ERROR * box_size(track.box)
        return other.box + np.array([-grow, -grow, grow, grow])

    def update(self, t: float, people: list[np.ndarray], slots: list[int | None] | None = None) -> list[int]:
        """Track ids of ``people`` (each (33, ≥4) landmarks: x, y pixels, z, visibility) seen at ``t`` seconds,
        in their order. ``slots``: the landmark slot that followed each (None: unknown)."""
        cfg = self.config
        t = float(t)
        slots = list(slots) if slots is not None else [None] * len(people)
        if len(slots) != len(people):
            raise ValueError(f"{len(people)} people but {len(slots)} slots")
        self._tracks = [tr for tr in self._tracks if t - tr.last_t <= cfg.lost_keep_s or self._still_hidden(tr, t)]
        lms_list = [np.asarray(p, dtype=np.float64) for p in people]
        boxes = [landmark_box(p) for p in lms_list]
        pairs = []
        for ti, tr in enumerate(self._tracks):
            for pi, (lms, box) in enumerate(zip(lms_list, boxes, strict=True)):
                s = self.similarity(tr, lms, box, slots[pi], t)
                if s >= cfg.min_similarity:
                    pairs.append((s, ti, pi))
        # hidden tracks last: their way runs behind the person covering them, whose own track must keep them
        pairs.sort(key=lambda p: (self._tracks[p[1]].behind is not None, -p[0]))
        ids: list[int | None] = [None] * len(people)
        used: set[int] = set()
        for _s, ti, pi in pairs:
            if ti in used or ids[pi] is not None:
                continue
            used.add(ti)
            tr = self._tracks[ti]
            self._advance(tr, t, lms_list[pi], boxes[pi], slots[pi])
            ids[pi] = tr.id
        self._note_hidden(ids, boxes)
        self._note_free(ids, boxes)
        for pi, lms in enumerate(lms_list):
            if ids[pi] is None and np.isfinite(boxes[pi]).all():
                tr = _Track(self._next_id, t, lms, slots[pi])
                self._next_id += 1
                self._tracks.append(tr)
                ids[pi] = tr.id
            elif ids[pi] is None:
                ids[pi] = self._next_id  # no landmark with coordinates: an id of its own, not tracked
                self._next_id += 1
        self._last_t = t
        return [int(i) for i in ids]

    def _still_hidden(self, tr: _Track, t: float) -> bool:
        """Whether a track lost behind someone is kept: within ``hidden_keep_s`` and the person covering it
        seen in the last frame."""
        if tr.behind is None or t - tr.last_t > self.config.hidden_keep_s:
            return False
        return any(o.id == tr.behind and o.last_t == self._last_t for o in self._tracks)

    def _note_hidden(self, ids: list[int | None], boxes: list[np.ndarray]) -> None:
        """Each track seen in the last frame and not now whose last box overlaps the box of someone seen now is
        behind them (the one covering most of its box)."""
        seen_now = {i for i in ids if i is not None}
        for tr in self._tracks:
            if tr.id in seen_now or tr.last_t != self._last_t or self._last_t is None:
                continue
            cover = [(_intersection(tr.box, box), i) for i, box in zip(ids, boxes, strict=True)
                     if i is not None and np.isfinite(box).all()]
            best = max(cover, default=(0.0, None))
            tr.behind = best[1] if best[0] > 0.0 else None

    def _note_free(self, ids: list[int | None], boxes: list[np.ndarray]) -> None:
        """Each track seen now whose box touches nobody else's keeps its velocity as ``free_velocity``."""
        for tr in self._tracks:
            if tr.id not in ids:
                continue
            mine = boxes[ids.index(tr.id)]
            if not any(_intersection(mine, box) > 0.0 for i, box in zip(ids, boxes, strict=True)
                       if i != tr.id and np.isfinite(box).all()):
                tr.free_velocity = tr.velocity.copy()

    @staticmethod
    def _advance(tr: _Track, t: float, lms: np.ndarray, box: np.ndarray, slot: int | None) -> None:
        dt = t - tr.last_t
        if dt > 0:
            v = (_centre(box) - _centre(tr.box)) / dt
            tr.velocity = v if tr.hits == 1 else 0.5 * tr.velocity + 0.5 * v
        new_props = proportions(lms)
        known = np.isfinite(new_props)
        mix = np.where(np.isfinite(tr.props), 0.9 * tr.props + 0.1 * new_props, new_props)
        tr.props = np.where(known, mix, tr.props)
        tr.lms, tr.box, tr.last_t, tr.slot, tr.behind = lms.copy(), box, t, slot, None
        tr.hits += 1


def _nearest_on_way(way: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """The point of the segment from 0 to ``way`` (pixels) nearest ``offset``."""
    n2 = float(way @ way)
    if not n2 > 0.0:
        return np.zeros(2)
    return way * min(max(float(offset @ way) / n2, 0.0), 1.0)
