"""Several people: :class:`PeopleFalls`, a :class:`~falls.detector.FallDetector` of their own for each person.

A frame hands over its people, each as ``(person, result, landmarks)``: the track id (``None`` for the one
person of a stream without ids: a frame without ``people``), their fit result and their 2D landmarks. Every
person gets their own detector (own motion, own standing height, own event and alarm timer); the messages say
whose fall it is.

* **The camera is shared, metres are not.** A new person's detector starts from the gravity the main detector
  learned (tilt and roll, from bodies or image lines: :meth:`falls.camera_geometry.CameraGeometry.state`) and
  goes on learning from its own person. Not the floor or the standing height learned from the other person:
  without depth, a fit's metres follow the body size it assumes, so a floor seen under one person's feet is
  at another height in a second person's metres (on urfd_dev with a bystander beside, a floor taken over from
  the bystander raised a false alarm on a daily activity that raised none alone); each person learns their
  own, from the configured height to begin with. The *main* detector is the one of the frame's
  own person (the one followed longest, the FitMsg's ``result``): its geometry is the one shown in the status and
  kept across restarts. An IMU's gravity or the depth floor is handed to every detector (:meth:`each`).
* **A person out of view is still watched.** Each frame, every known person not in it is fed a "not in view"
  frame at the frame's capture time: the lost-after-descent rule (a fall that ends out of sight) and the alarm
  timer run for them as for one person alone; missing frames are never evidence of recovery.
* **Coming back.** The landmark stage's tracker gives a person lost for more than its ``lost_keep_s`` (2 s) a new
  id, and may give a new one to a body whose box changed too fast (a fall). A new id is matched to a person not
  in the frame when its landmark box centre is near that person's last box (``REMATCH_EVENT_REL`` of the last
  box's longest side for someone whose fall event is under way, a person lying where they fell re-found by the
  rotated retry, or who was seen less than ``RECENT_S`` ago; ``REMATCH_REL`` for anyone else), nearest first.
  The messages of a re-matched person then carry ``person_match``: the previous id, the seconds unseen, the
  distance (box sides) and ``sure`` (1 at the same spot, 0 at the limit). The person of a stream without ids,
  when the first frame with ids comes, is its frame's own person if they were in view the frame before (the
  landmark stage keeps the person followed longest as the frame's own), else matched like anyone else.
* **No frames.** :meth:`PeopleFalls.tick` runs every person's alarm timer on without a frame (the publisher
  calls it when no frame came for a while: the camera blind, a recording ended, the pipeline stalled).
* **Forgetting.** A person unseen for ``FORGET_S`` with no event under way is forgotten; one whose event is
  under way (``down`` or ``alarm``) is kept until re-matched or seen recovering; at most ``MAX_KEPT`` people are
  kept (the longest unseen without an event go first, then with one).

* **Who is who** (``falls.household`` configured): each person standing upright in view gives stature samples
  (:mod:`falls.stature`, only with a measured floor) to :class:`falls.household.Household`, which says who is a
  member, a visitor or not known; :meth:`PeopleFalls.followed` is whom status, history and ROS 2 follow.

Messages of a person with a track id carry ``person`` (the id) and ``root_cam_m`` (where the person was last
fitted: the pelvis in camera axes, metres; None when never fitted), with a household also ``member`` and
``household``; the one person of a stream without ids and no household gets none of them, so its messages are
what a single :class:`FallDetector` gives.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from posed.falls.detector import FallDetector
from posed.falls.event import FallEvent
from posed.falls.household import Household
from posed.falls.stature import stature_m
from posed.fitting import FitResult

FORGET_S = 5.0             # a person unseen this long (capture seconds) with no event under way is forgotten
MAX_KEPT = 8               # people kept at most (present and unseen)
# A new id near where someone was lost is taken for them. Someone who fell and lies still is re-found where they
# were last seen, give or take the change from standing to lying: their lying body's box centre moves by up to
# half a standing height (a box side) from the standing one. Anyone else walks: half a box side is about the
# distance covered in the tracker's 2 s at a slow elderly gait (0.3-0.5 m/s against a 1.6 m side), beyond it a
# match is a guess.
REMATCH_EVENT_REL = 1.0
REMATCH_REL = 0.5
# A track that ended this recently, with a new one starting near it, is the same body (the tracker let go of a
# person whose box changed fast: a fall from standing to lying moves the box centre by up to half a side in
# 0.2-0.3 s): the wider limit applies, as for someone whose event is under way.
RECENT_S = 0.5
VISIBLE = 0.5              # a landmark counts for the box above this visibility


@dataclass
class _Person:
    detector: FallDetector
    last_t: float | None = None           # last frame with their landmarks (capture seconds)
    box: np.ndarray | None = None         # their last landmark box: xmin, ymin, xmax, ymax (pixels)
    root_cam_m: tuple[float, float, float] | None = None
    match: dict | None = None             # how they were matched again after a new id (person_match)


class PeopleFalls:
    """One fall detector per person (module doc): ``first`` is the main one to begin with (the stream's one
    person); ``make_detector()`` builds one for each further person (default: the same config as ``first``)."""

    def __init__(self, first: FallDetector, make_detector: Callable[[], FallDetector] | None = None) -> None:
        self._make = make_detector or (lambda: FallDetector(first.cfg, first.robot_id, first.fit_frame))
        self.main_key: int | None = None
        self.people: dict[int | None, _Person] = {None: _Person(first)}
        self._prev_t: float | None = None
        self.rematches = 0
        self.household = Household(getattr(first.cfg, "household", ()))
        self.metric: str | None = None            # why no stature can be measured (None: it can)
        self.in_frame: dict[int | None, FitResult] = {}   # the last frame's people and their results

    @property
    def main(self) -> FallDetector:
        """The detector of the frame's own person (its geometry is the camera's as shown and kept)."""
        return self.people[self.main_key].detector

    def each(self, fn: Callable[[FallDetector], object]) -> None:
        """Apply ``fn`` to every person's detector (IMU gravity, depth floor)."""
        for p in self.people.values():
            fn(p.detector)

    def watching(self) -> dict:
        """For the status: the people watched, those in view and their detector states."""
        return {"people": len(self.people), "rematches": self.rematches,
                "states": {str(k) if k is not None else "-": p.detector.state for k, p in self.people.items()}}

    def update(self, people: list[tuple[int | None, FitResult, np.ndarray | None]], t: float, seq: int,
               image_size, intrinsics=None) -> list[FallEvent]:
        """Feed one frame (capture time ``t``): ``people`` is ``[(track id or None, result, landmarks)]``, the
        frame's own person first (an ``ok: false`` result and None landmarks when nobody is in it). Returns
        the messages this frame caused, each tagged with its person (module doc)."""
        if self._prev_t is not None and t < self._prev_t:      # the stream started again: ids start again too
            self._restart()
        out: list[FallEvent] = []
        present: set[int | None] = {pid for pid, _, lms in people if pid in self.people}
        in_frame: dict[int | None, FitResult] = {}
        for i, (pid, result, landmarks) in enumerate(people):
            if pid is None and landmarks is None and None not in self.people:
                continue       # nobody in view in a stream with ids: everyone is fed "not in view" below
            key = self._key_for(pid, landmarks, present)
            if i == 0:
                self.main_key = key
            present.add(key)
            in_frame[key] = result
            person = self.people[key]
            box = _box(landmarks) if landmarks is not None else None
            if box is not None:
                person.last_t, person.box = t, box
            if getattr(result, "ok", False) and getattr(result, "root_cam_m", None) is not None:
                person.root_cam_m = result.root_cam_m
            events = person.detector.update(result, landmarks, image_size, intrinsics)
            if self.household and landmarks is not None:
                self._measure(key, person.detector, landmarks)
            out += self._tag(key, person, events)
        for key, person in list(self.people.items()):
            if key in present:
                continue
            gone = FitResult.failure(seq, t, "not in view")
            out += self._tag(key, person, person.detector.update(gone, None, image_size, intrinsics))
        self._forget(t)
        self._prev_t = t
        self.in_frame = in_frame
        return out

    def tick(self, t: float) -> list[FallEvent]:
        """No frame for a while: every person's alarm timer runs on to capture time ``t``
        (:meth:`FallDetector.tick`), each message tagged with its person. Nothing else changes: who is in view,
        the last frame's time (a frame older than ``t`` coming later is no restart of the stream)."""
        out: list[FallEvent] = []
        for key, person in list(self.people.items()):
            out += self._tag(key, person, person.detector.tick(t))
        return out

    def detector_of(self, event_id: str) -> tuple[int | None, FallDetector] | None:
        """The person (key) and detector whose event under way has ``event_id``; None when nobody's has."""
        for key, person in self.people.items():
            if person.detector.event_id == event_id:
                return key, person.detector
        return None

    # ------------------------------------------------------------------ the household

    def _measure(self, key: int | None, det: FallDetector, landmarks: np.ndarray) -> None:
        """A stature sample of a person standing upright, when the camera's floor is measured (module doc)."""
        floor = det.camera.metric_floor()
        if floor is None:
            self.metric = ("no measured floor: set falls.camera_height_m and camera_tilt_deg as measured "
                           "(falls.camera_geometry: measured) or use a depth camera")
            return
        self.metric = None
        f = det.last_features
        if f is None or not f.straight_body or f.trunk_incl_deg > det.cfg.upright_trunk_deg \
                or det.last_camera is None:
            return
        h = stature_m(landmarks, det.last_camera, det.camera.gravity, floor, det.cfg.min_visibility)
        if h is not None:
            self.household.observe(key, h)

    def followed(self) -> int | None | bool:
        """Whom status and history follow this frame: the person in view recognised as the first-listed
        household member in view; else the first person in view (the frame's own first) not known to be a
        visitor; False when only visitors are in view (or nobody)."""
        present = list(self.in_frame)
        if not self.household:
            return present[0] if present else False
        ranked = [(r, k) for k in present for r in [self.household.rank(k)] if r is not None]
        if ranked:
            return min(ranked, key=lambda x: x[0])[1]
        return next((k for k in present if not self.household.who(k)["visitor"]), False)

    def household_status(self) -> dict:
        """For the status: the members, whether stature can be measured, each person in view as recognised."""
        followed = self.followed()
        return {"members": [m.name for m in self.household.members], "stature": self.metric or "measured",
                "in_view": [{"person": k, **self.household.who(k)} for k in self.in_frame],
                "followed": None if followed is False else followed}

    # ------------------------------------------------------------------ who is who

    def _key_for(self, pid: int | None, landmarks: np.ndarray | None, present: set) -> int | None:
        if pid in self.people:
            return pid
        if None in self.people and self._seen_last_frame(self.people[None]):
            self.people[pid] = self.people.pop(None)            # the stream's one person got their id
            self.household.rename(None, pid)
            return pid
        box = _box(landmarks) if landmarks is not None else None
        best = self._rematch(box, present) if box is not None else None
        if best is not None:
            old, match = best
            person = self.people.pop(old)
            person.match = match
            self.people[pid] = person
            self.household.rename(old, pid)
            self.rematches += 1
            return pid
        self.people[pid] = _Person(self._new_detector())
        return pid

    def _seen_last_frame(self, person: _Person) -> bool:
        return person.last_t is not None and self._prev_t is not None and person.last_t >= self._prev_t

    def _rematch(self, box: np.ndarray, present: set) -> tuple[int | None, dict] | None:
        """The person not in this frame that a new id at ``box`` most likely is, with the match's evidence."""
        centre = 0.5 * (box[:2] + box[2:])
        best = None
        for key, p in self.people.items():
            if key in present or p.box is None or p.last_t is None:
                continue
            side = float(max(p.box[2] - p.box[0], p.box[3] - p.box[1], 1.0))
            dist = float(np.linalg.norm(centre - 0.5 * (p.box[:2] + p.box[2:]))) / side
            unseen = (self._prev_t - p.last_t) if self._prev_t is not None else 0.0
            limit = REMATCH_EVENT_REL if p.detector.state != "up" or unseen <= RECENT_S else REMATCH_REL
            if dist <= limit and (best is None or dist / limit < best[1]):
                best = (key, dist / limit, dist, unseen)
        if best is None:
            return None
        key, frac, dist, unseen = best
        return key, {"previous": key, "unseen_s": round(float(unseen), 2), "distance_rel": round(dist, 3),
                     "sure": round(1.0 - frac, 3)}

    def _new_detector(self) -> FallDetector:
        det = self._make()
        state = self.main.camera.state()
        state["floor"] = state["standing_pelvis"] = None    # in the other person's metres (module doc)
        if det.camera.restore(state) is None:
            det.camera.restored = False
        return det

    def _forget(self, t: float) -> None:
        for key, p in list(self.people.items()):
            if key == self.main_key or p.detector.state != "up":
                continue
            if p.last_t is None or t - p.last_t > FORGET_S:
                del self.people[key]
                self.household.forget(key)
        while len(self.people) > MAX_KEPT:
            unseen = [(p.detector.state != "up", p.last_t if p.last_t is not None else -math.inf, k)
                      for k, p in self.people.items() if k != self.main_key]
            gone = min(unseen, key=lambda x: (x[0], x[1]))[2]
            del self.people[gone]
            self.household.forget(gone)

    def _restart(self) -> None:
        main = self.people[self.main_key]
        main.last_t, main.box, main.match = None, None, None
        self.people = {None: main}
        self.main_key = None
        self.household = Household(self.household.members)
        self.in_frame = {}

    def _tag(self, key: int | None, person: _Person, events: list[FallEvent]) -> list[FallEvent]:
        if not events:
            return events
        tags: dict = {}
        if key is not None:
            tags = {"person": key, "root_cam_m": None if person.root_cam_m is None else
                    [round(float(v), 3) for v in person.root_cam_m]}
            if person.match is not None:
                tags["person_match"] = dict(person.match)
        if self.household:
            who = self.household.who(key)
            tags["member"] = who["member"]
            tags["household"] = {k: who[k] for k in ("visitor", "sure", "stature_m", "samples")}
        return [replace(e, extra={**e.extra, **tags}) for e in events] if tags else events


def _box(landmarks: np.ndarray) -> np.ndarray | None:
    lm = np.asarray(landmarks, float)
    seen = np.isfinite(lm[:, :2]).all(1) & (lm[:, 3] > VISIBLE if lm.shape[1] > 3 else True)
    if seen.sum() < 3:
        return None
    xy = lm[seen, :2]
    return np.concatenate([xy.min(0), xy.max(0)])
