"""Several people per frame: :class:`MultiPoseLandmarker`, one BlazePose landmark pass per person.

Up to ``landmarks.max_people`` *slots*, each a :class:`~landmarks.pipeline.PoseLandmarker` of its own (its own
ROI tracking, one-euro filters and rotated ROI) sharing the two onnxruntime sessions. Per frame:

1. Every slot that follows someone runs its landmark pass on its ROI (MediaPipe's video mode, per person);
   a slot whose pose flag drops below ``min_tracking_confidence`` lets its person go.
2. Two slots that ended on the same body (landmark overlap, :func:`landmarks.tracks.oks` > ``SAME_BODY``: the
   ROI of a person walking behind another slid onto the one in front) are merged: the slot whose landmarks
   jumped more from its own last frame lets go.
3. The detector runs when nobody was followed at the start of the frame (exactly as the one-person landmarker)
   and, while a slot is free and someone is followed, every ``redetect_every`` frames (a person entering).
   Its detections (MediaPipe's weighted NMS keeps every separate person, best first) that are not the hips of
   someone already followed start free slots, best first; when nobody is followed, finds nobody and
   ``rotate_on_miss`` is on, the frame rotated by +90° then −90° is tried (a person lying on the floor).
   The search for a newcomer while someone is followed runs *ahead*: started in a background thread on the
   frame where it is due (the people followed blanked out: their landmark boxes, but where someone was lost a
   moment ago only their bodies, :func:`_reopened`), its detections collected by the next frame,
   which starts their landmark passes. So it is off the frame's critical path (the detector runs in the time
   between frames, or on the other core alongside the next frame's landmark passes), at the price of one
   frame (0.1 s at 10 fps) later for a newcomer; the output is the same whatever the timing (the next frame
   always waits for it: the detector is never used by two threads at once).
4. :class:`~landmarks.tracks.PersonTracker` gives each person a track id.

The frame's ``landmarks``/``world`` are those of the person followed longest (the oldest track); from the first
frame with two people on, every frame also carries ``people`` (all persons, by id). With one person in view the
first slot does exactly what :class:`PoseLandmarker` does, so the output is byte-identical to it (unless the
detector, run every ``redetect_every`` frames, finds a second person where there is none).
"""

from __future__ import annotations

import time
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from posed.landmarks.blanking import body_mask
from posed.landmarks.config import LandmarkConfig
from posed.landmarks.crop import detector_input
from posed.landmarks.detector import Detection
from posed.landmarks.pipeline import (
    FALLBACK_ROTATIONS,
    PoseLandmarker,
    PoseResult,
    check_image,
    rotate_image,
    unrotate_points,
)
from posed.landmarks.recording import LandmarkFrame, PersonLandmarks
from posed.landmarks.roi import roi_from_alignment
from posed.landmarks.runtime import DetectorRunner, LandmarkRunner
from posed.landmarks.tracks import PersonTracker, TrackerConfig, body_overlap, box_iou, landmark_box

REDETECT_EVERY = 5     # frames between detector runs looking for someone new while a slot is free
SAME_BODY = 0.5        # landmark overlap above which two slots follow the same body
NEW_BOX_IOU = 0.4      # a new body sharing more of its box with someone followed is taken for them
NEW_OVERLAP = 0.25     # ... or more of its landmarks
SAME_HIPS = 0.15       # a detection whose hip centre is this close (fraction of a followed ROI's side) is them


@dataclass(frozen=True, eq=False)
class PersonResult:
    """One person of a frame: track ``id``, the ``slot`` that followed them, the slot's :class:`PoseResult`."""

    id: int
    slot: int
    result: PoseResult


@dataclass(frozen=True, eq=False)
class MultiPoseResult:
    """Everything found in one frame: ``frame`` (what ``process`` returns), ``people`` (by track id),
    ``primary`` (the track id of the frame's own landmarks, None when nobody), whether the detector ran and
    ``timings_ms`` (milliseconds per step, summed over people; ``landmark_passes`` counts passes)."""

    frame: LandmarkFrame
    people: tuple[PersonResult, ...] = ()
    primary: int | None = None
    detector_ran: bool = False
    timings_ms: dict = field(default_factory=dict)


class MultiPoseLandmarker:
    """BlazePose full for up to ``config.max_people`` people (see the module doc); same calls as
    :class:`PoseLandmarker`."""

    def __init__(self, config: LandmarkConfig | None = None, models_dir: Path | None = None, *,
                 detector: DetectorRunner | None = None, landmark_model: LandmarkRunner | None = None,
                 tracker: TrackerConfig | None = None, redetect_every: int = REDETECT_EVERY) -> None:
        first = PoseLandmarker(config, models_dir, detector=detector, landmark_model=landmark_model)
        self.config = first.config
        self.detector, self.landmark_model = first.detector, first.landmark_model
        self.slots = [first] + [PoseLandmarker(self.config, detector=self.detector,
                                               landmark_model=self.landmark_model)
                                for _ in range(self.config.max_people - 1)]
        self.tracker = PersonTracker(tracker)
        self.redetect_every = max(1, int(redetect_every))
        self._prev: dict[int, np.ndarray] = {}   # slot -> its landmarks of the last frame
        self._since_detect = 0
        self.several_seen = False
        self.last_result: MultiPoseResult | None = None
        self._pool: ThreadPoolExecutor | None = None
        self._pending: Future | None = None

    def reset(self) -> None:
        """Forget everyone (the next frame runs the detector); track ids keep counting up."""
        self._collect()                          # a search under way ends first; its detections are dropped
        for slot in self.slots:
            slot.reset()
        self.tracker.reset()
        self._prev.clear()
        self._since_detect = 0
        self.several_seen = False
        self.last_result = None

    def warmup(self) -> None:
        self.slots[0].warmup()

    def process(self, image_bgr: np.ndarray, t: float, seq: int) -> LandmarkFrame:
        """The frame's landmarks (the person followed longest) and, once two people were seen, ``people``."""
        return self.process_full(image_bgr, t, seq).frame

    def process_full(self, image_bgr: np.ndarray, t: float, seq: int) -> MultiPoseResult:
        image = check_image(image_bgr)
        t, seq = float(t), int(seq)
        if not self.config.tracking:
            for slot in self.slots:
                slot.reset()
            self._prev.clear()
        timings: dict[str, float] = {"landmark_passes": 0}
        ahead = self._collect()      # a newcomer search started on the frame before (someone was followed)
        found: dict[int, PoseResult] = {}
        followed_at_start = [i for i, s in enumerate(self.slots) if s._roi is not None]
        for i in followed_at_start:
            r = self.slots[i].landmark_pass(image, self.slots[i]._roi, t, seq)
            _add_timings(timings, r.timings_ms)
            if r.frame.landmarks is not None:
                found[i] = r
        self._merge_same_bodies(found)

        detector_ran = False
        self._since_detect += 1
        free = [i for i, s in enumerate(self.slots) if s._roi is None and i not in found]
        if free and not followed_at_start:
            detector_ran = True
            self._since_detect = 0
            self._detect_new(image, t, seq, found, free, timings)
        elif ahead is not None:                 # the search started on the frame before: start its newcomers
            dets, ms = ahead
            timings["detector"] = timings.get("detector", 0.0) + ms
            detector_ran = True
            if free and found:
                h, w = image.shape[:2]
                self._start_slots(image, t, seq, found, free,
                                  [d for d in dets if not self._is_followed(d, w, h, found)], 0, timings)
        free = [i for i, s in enumerate(self.slots) if s._roi is None and i not in found]
        if free and found and self._since_detect >= self.redetect_every and followed_at_start:
            self._since_detect = 0
            self._look_ahead(image, found)

        ordered = sorted(found)
        ids = self.tracker.update(t, [found[i].frame.landmarks for i in ordered], ordered)
        people = tuple(sorted((PersonResult(pid, i, found[i]) for pid, i in zip(ids, ordered, strict=True)),
                              key=lambda p: p.id))
        for i in list(self._prev):
            if i not in found:
                del self._prev[i]
        for i in ordered:
            self._prev[i] = found[i].frame.landmarks
        self.several_seen = self.several_seen or len(people) > 1
        primary = self.tracker.longest_followed([p.id for p in people])
        if primary is None:
            frame = LandmarkFrame(seq, t, None)
        else:
            frame = next(p.result.frame for p in people if p.id == primary)
        if self.several_seen:
            frame = replace(frame, people=tuple(PersonLandmarks(p.id, p.result.frame.landmarks,
                                                                p.result.frame.world) for p in people))
        result = MultiPoseResult(frame, people, primary, detector_ran, timings)
        self.last_result = result
        return result

    # -- steps -------------------------------------------------------------------------------------------------

    def _merge_same_bodies(self, found: dict[int, PoseResult]) -> None:
        """Two slots on one body: the one whose landmarks jumped more from its last frame (or a new one) goes."""
        for i in sorted(found):
            for j in sorted(found):
                if j <= i or i not in found or j not in found:
                    continue
                a, b = found[i].frame.landmarks, found[j].frame.landmarks
                if body_overlap(a, b) <= SAME_BODY:
                    continue
                stay = [body_overlap(self._prev[k], found[k].frame.landmarks) if k in self._prev else -1.0
                        for k in (i, j)]
                drop = j if stay[0] >= stay[1] else i
                self.slots[drop].reset()
                del found[drop]

    @staticmethod
    def _overlaps_someone(lms: np.ndarray, found: dict[int, PoseResult]) -> bool:
        """A newly detected body that shares most of its box (IoU > NEW_BOX_IOU) or its landmarks
        (:func:`landmarks.tracks.body_overlap` > NEW_OVERLAP) with someone already followed is taken for them
        (a second, worse fit of the same person, or someone hidden behind them: followed again once apart)."""
        box = landmark_box(lms)
        for r in found.values():
            other = r.frame.landmarks
            if box_iou(box, landmark_box(other)) > NEW_BOX_IOU or body_overlap(lms, other) > NEW_OVERLAP:
                return True
        return False

    def _is_followed(self, det: Detection, width: int, height: int, found: dict[int, PoseResult]) -> bool:
        hips = det.keypoints_px(width, height)[0]
        for r in found.values():
            if r.aux_landmarks is None or r.roi is None:
                continue
            if np.hypot(*(hips - r.aux_landmarks[0, :2])) < SAME_HIPS * r.roi.size:
                return True
        return False

    def _detections(self, image: np.ndarray, degrees: int) -> list[Detection]:
        """Every detection in ``image`` turned by ``degrees`` (0 = as is), normalized to the unturned frame."""
        h, w = image.shape[:2]
        turned = image if degrees == 0 else rotate_image(image, degrees)
        tensor, padding = detector_input(turned)
        out = self.detector(tensor)
        dets = self.slots[0].decoder(out.boxes, out.scores, padding)
        if degrees == 0:
            return dets
        rh, rw = turned.shape[:2]
        scale = np.array([rw, rh], dtype=np.float64)
        back = []
        for det in dets:
            kps = unrotate_points(det.keypoints * scale, degrees, w, h) / np.array([w, h], dtype=np.float64)
            x0, y0, x1, y1 = det.box * np.tile(scale, 2)
            corners = unrotate_points(np.array([[x0, y0], [x1, y1]]), degrees, w, h)
            box = np.concatenate([corners.min(axis=0), corners.max(axis=0)]) / np.array([w, h, w, h], float)
            back.append(Detection(det.score, box, kps))
        return back

    def _look_ahead(self, image: np.ndarray, found: dict[int, PoseResult]) -> None:
        """Start the search for a newcomer on this frame (the people followed blanked out) in the background;
        the next frame collects its detections (:meth:`_collect`) and starts their landmark passes."""
        if self._pool is None:
            self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="newcomer-search")
        own = image.copy()          # the caller may draw on its image once this frame is done
        bodies = [r.frame.landmarks for r in found.values() if r.frame.landmarks is not None]
        boxes = [landmark_box(lms) for lms in bodies]
        cfg = self.tracker.config
        t = next(iter(found.values())).frame.t
        lost = [tr.box for tr in self.tracker.tracks if cfg.lost_after_s < t - tr.last_t <= cfg.lost_keep_s]

        def search() -> tuple[list[Detection], float]:
            t0 = time.perf_counter()
            # the box painting works in place: on a copy only when lost people's boxes are shown again from own
            dets = self._detections(_reopened(_blanked(own.copy() if lost else own, boxes), own, bodies, lost), 0)
            return dets, (time.perf_counter() - t0) * 1e3

        self._pending = self._pool.submit(search)

    def _collect(self) -> tuple[list[Detection], float] | None:
        """The detections of the search started on the frame before (waiting for it if it still runs: the
        detector is never used by two threads at once), or None."""
        job, self._pending = self._pending, None
        return None if job is None else job.result()

    def _detect_new(self, image: np.ndarray, t: float, seq: int, found: dict[int, PoseResult], free: list[int],
                    timings: dict[str, float]) -> None:
        h, w = image.shape[:2]
        # the turned retries (a person lying on the floor) only when nobody is followed: while someone is, a
        # redetection every few frames looking for a newcomer costs one detector run, not three
        rotations = (0,) + (FALLBACK_ROTATIONS if self.config.rotate_on_miss and not found else ())
        # BlazePose's detector sees the most prominent person: with one in full view its scores elsewhere fall
        # below 0.05 (a second, smaller person it finds at 0.84 alone). So the people followed are blanked out
        # of the image it looks at; the landmark passes still see the whole frame.
        seen = _without_followed(image, found) if found else image
        for degrees in rotations:
            t0 = time.perf_counter()
            dets = [d for d in self._detections(seen, degrees) if not self._is_followed(d, w, h, found)]
            timings["detector"] = timings.get("detector", 0.0) + (time.perf_counter() - t0) * 1e3
            if not dets:
                continue
            self._start_slots(image, t, seq, found, free, dets, degrees, timings)
            return
        if not found:
            for slot in self.slots:
                slot.smoother.reset()

    def _start_slots(self, image: np.ndarray, t: float, seq: int, found: dict[int, PoseResult], free: list[int],
                     dets: list[Detection], degrees: int, timings: dict[str, float]) -> None:
        """A landmark pass in a free slot for each detection, best first; one that lands on someone already
        followed (or finds nobody) frees its slot again."""
        h, w = image.shape[:2]
        for det in dets:
            if not free:
                break
            slot = free[0]
            kps = det.keypoints_px(w, h)
            r = self.slots[slot].landmark_pass(image, roi_from_alignment(kps[0], kps[1]), t, seq,
                                               detection=det, rotation=degrees, detector_ran=True)
            _add_timings(timings, r.timings_ms)
            if r.frame.landmarks is None or self._overlaps_someone(r.frame.landmarks, found):
                self.slots[slot].reset()
                continue
            found[slot] = r
            self._merge_same_bodies(found)      # a new slot on someone already followed goes again
            free[:] = [i for i, s in enumerate(self.slots) if s._roi is None and i not in found]


BLANK_MARGIN = 0.1      # a followed person's landmark box, enlarged by this fraction per side, is blanked


def _without_followed(image: np.ndarray, found: dict[int, PoseResult]) -> np.ndarray:
    """``image`` with the landmark box of everyone in ``found`` filled with the image's mean colour."""
    boxes = [landmark_box(r.frame.landmarks) for r in found.values() if r.frame.landmarks is not None]
    return _blanked(image.copy(), boxes)


def _fill_colour(image: np.ndarray) -> np.ndarray:
    """What a painted-out region is filled with: the image's mean colour, taken on every 8th pixel of every 8th
    row (the same colour to a unit, 60x less work)."""
    return image[::8, ::8].reshape(-1, image.shape[2]).mean(axis=0).astype(image.dtype)


def _blanked(out: np.ndarray, boxes: list[np.ndarray]) -> np.ndarray:
    """``out`` (changed in place) with each box, enlarged by ``BLANK_MARGIN`` per side, filled with the image's
    mean colour (:func:`_fill_colour`)."""
    fill = _fill_colour(out)
    h, w = out.shape[:2]
    for box in boxes:
        if not np.isfinite(box).all():
            continue
        mx, my = BLANK_MARGIN * (box[2] - box[0]), BLANK_MARGIN * (box[3] - box[1])
        x0, y0 = int(max(0, box[0] - mx)), int(max(0, box[1] - my))
        x1, y1 = int(min(w, box[2] + mx + 1)), int(min(h, box[3] + my + 1))
        if x1 > x0 and y1 > y0:
            out[y0:y1, x0:x1] = fill
    return out


def _reopened(blanked: np.ndarray, image: np.ndarray, bodies: list[np.ndarray], lost: list[np.ndarray]) -> np.ndarray:
    """``blanked`` (changed in place) with the last box of each person lost a moment ago (``lost``: tracks
    unseen for more than ``lost_after_s`` and at most ``lost_keep_s``) shown again as in ``image``, but for the
    followed people's bodies (:func:`landmarks.blanking.body_mask`): someone hidden behind a person followed
    reappears there, in what that person's box covers but their body does not."""
    if not lost:
        return blanked
    h, w = image.shape[:2]
    fill = _fill_colour(image)
    body = np.zeros((h, w), bool)
    for lms in bodies:
        body |= body_mask((h, w), lms)
    for box in lost:
        if not np.isfinite(box).all():
            continue
        x0, y0 = int(max(0, box[0])), int(max(0, box[1]))
        x1, y1 = int(min(w, box[2] + 1)), int(min(h, box[3] + 1))
        if x1 > x0 and y1 > y0:
            region = blanked[y0:y1, x0:x1]
            region[:] = image[y0:y1, x0:x1]
            region[body[y0:y1, x0:x1]] = fill
    return blanked


def _add_timings(total: dict[str, float], step: dict) -> None:
    for k, v in step.items():
        total[k] = total.get(k, 0.0) + v
    if "landmark_model" in step:
        total["landmark_passes"] = total.get("landmark_passes", 0) + 1
