"""Fall detection in the publisher stage: the :mod:`falls` detector run on every fit, in capture order.

Several people (a frame with ``people``: the FitMsg's ``others``): each person has a detector of their own
(:class:`falls.people.PeopleFalls`); their messages carry ``person`` and ``root_cam_m``. The frame's own
person's detector is the one whose geometry is in the status and kept across restarts; the IMU's gravity and
the depth floor go to every person's.

Every FitMsg is fed (also frames without a person: the alarm timer runs on the capture timestamps, the one
clock), with its 2D landmarks, image size and camera intrinsics. When no frame comes for a while (the camera
blind or unplugged, a recording ended, the pipeline stalled) the publisher calls :meth:`FallWatch.tick`: the
alarm timers run on without frames (docs/falls.md, "The alarm without frames"). A detector that raises must not stop the
poses: the frame then yields no event, the stage's error counter goes up and the failure is logged (the
first three, then every hundredth).

IMU gravity: a frame whose landmark frame carries ``gravity`` (three numbers, the accelerometer's down
vector in the colour camera's axes, any length: ``LandmarkFrame.gravity``, filled by a RealSense camera or
recording with an accelerometer through hal.imu, or a ``*.landmarks.jsonl`` line's ``"gravity"``) sets the
detector's gravity when ``falls.imu_gravity`` is on. A malformed one (kept in the frame's ``extra``) is
counted and logged, and the gravity in use is kept.

The floor from depth: a frame whose landmark frame carries ``extra["floor"]`` (the landmark stage's plane
measured in the depth image about once a second, :mod:`daemon.stages.depth_floor`, or a recording line's
``"floor"``) gives the detector the floor plane (``FallDetector.set_floor_plane``) when ``falls.floor_from_depth``
is on: the camera height, and the tilt and roll unless an IMU gives them, ahead of anything configured or
learned. Its evidence (height, tilt, roll, inliers and their fraction, rms residual, age, fit time, tries and
misses) is in the status (``falls.geometry.depth_floor``) and in each event's ``geometry``. A plane older than
``depth_floor.KEEP_S`` (30 s of capture time) is forgotten: the geometry goes back to the other sources. A
malformed one is counted (``bad_floor``) and logged, and the geometry in use is kept.

The camera's pose from the robot (``falls.camera_mount_from_bus``): the publisher sets :attr:`FallWatch.mount`
(:class:`daemon.stages.mount_feed.MountFeed`); each frame is given the pose in force at its capture time
(``FallDetector.set_camera_mount``: the gravity and the height ahead of every other source, with its evidence:
age at the frame, source, samples received), or none when no pose covers it (the other sources, as without it).

Kept across restarts: what the detector learned from people about the camera (gravity from their bodies or
image lines, the floor under their feet, their standing height, with the seconds of evidence behind each) is
written to ``state_file`` (per camera: :func:`geometry_file`) every ``SAVE_EVERY_S`` of capture time when it
changed and on :meth:`FallWatch.close`, and taken back at start-up unless it was learned under other configured
values (``falls.camera_*``); an unreadable file is set aside (``.corrupt-<unix time>``) with one warning.
"""

from __future__ import annotations

import json
import re
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np

from posed.daemon.messages import FitMsg
from posed.daemon.outbox.private import write_private
from posed.daemon.stages.depth_floor import KEEP_S as FLOOR_KEEP_S
from posed.falls import FallDetector, FallEvent, FallsConfig
from posed.falls.people import PeopleFalls
from posed.fitting import FitResult

LOG_FIRST_FAILURES = 3
LOG_FAILURE_EVERY = 100
SAVE_EVERY_S = 30.0        # capture seconds between writes of the learned geometry (when it changed)
GEOMETRY_PREFIX = "falls-geometry"


def geometry_file(state_dir: Path, source) -> Path:
    """The file that keeps what the fall detector learned about one camera (``source``: the ``source`` config
    section): ``falls-geometry-<type>-<serial, device or path>.json`` in the state dir (a RealSense without a
    serial: ``realsense-any``)."""
    kind = getattr(source, "type", "file")
    ident = {"realsense": getattr(source, "serial", "") or "any", "v4l2": str(getattr(source, "device", "")),
             "file": str(Path(getattr(source, "path", "") or "demo").expanduser().resolve())}.get(kind, kind)
    name = re.sub(r"[^A-Za-z0-9._-]+", "_", f"{kind}-{ident}").strip("_")[-120:]
    return Path(state_dir) / f"{GEOMETRY_PREFIX}-{name}.json"


class FallWatch:
    """Wraps a :class:`FallDetector` per person (:class:`falls.people.PeopleFalls`; ``detector`` is the first
    person's, None when ``falls.enabled`` is false: no events)."""

    def __init__(self, detector: FallDetector | None, log, on_error: Callable[[], None] = lambda: None,
                 state_file: Path | None = None) -> None:
        self.people = PeopleFalls(detector) if detector is not None else None
        self.log = log
        self.failures = 0
        self.bad_gravity = 0
        self.bad_floor = 0
        self._floor: tuple[float, list, float, dict] | None = None   # measured at, down, height, evidence
        self._floor_tries: dict = {}    # the last floor field's fit counters (tries, misses, fit_ms, prior)
        self._on_error = on_error
        self.state_file = Path(state_file) if state_file is not None and detector is not None else None
        self._saved: str | None = None
        self.mount = None               # the robot's camera poses (MountFeed: at(t), received), or None
        self.mount_in_force = False     # a robot pose covered the last frame
        self._save_t: float | None = None
        self.save_error: str | None = None
        if self.state_file is not None:
            self._load()

    @classmethod
    def from_config(cls, cfg: FallsConfig, robot_id: str, log, on_error: Callable[[], None] = lambda: None,
                    state_file: Path | None = None) -> FallWatch:
        """``state_file``: where the geometry learned from people is kept across restarts (:func:`geometry_file`;
        None: not kept)."""
        return cls(FallDetector(cfg, robot_id) if cfg.enabled else None, log, on_error, state_file)

    @property
    def detector(self) -> FallDetector | None:
        """The frame's own person's detector: its camera geometry is the one shown and kept."""
        return self.people.main if self.people is not None else None

    def status(self) -> dict:
        """For the status message: whether detection runs, the camera geometry in use (tilt, roll, floor and
        where each comes from: config, learned, body or imu; whether it was restored from the state dir),
        malformed IMU readings and detector failures."""
        if self.detector is None:
            return {"enabled": False}
        geometry = {k: (round(v, 3) if isinstance(v, float) else v) for k, v in self.detector.geometry.items()}
        if self._floor_tries and "depth_floor" not in geometry:
            geometry["depth_floor"] = dict(self._floor_tries)   # fitted, no floor found (yet)
        out = {"enabled": True, "geometry": geometry, "bad_gravity": self.bad_gravity, "bad_floor": self.bad_floor,
               "failures": self.failures}
        if self.save_error is not None:
            out["geometry_save_error"] = self.save_error
        if self.people.main_key is not None:        # several people seen: who is watched
            out["people"] = self.people.watching()
        if self.people.household:
            out["household"] = self.people.household_status()
        return out

    def followed(self, msg: FitMsg) -> FitResult:
        """The fit that the history keeps for this frame: the household member's when a household is configured
        and one is recognised in view (:meth:`falls.people.PeopleFalls.followed`); a frame with only visitors
        in view gives a "no person" result (the person cared for is not in view); otherwise the frame's own."""
        if self.people is None or not self.people.household:
            return msg.result
        key = self.people.followed()
        if key is False:
            return FitResult.failure(msg.result.seq, msg.result.t, "no person",
                                     others_in_view=len(self.people.in_frame))
        return self.people.in_frame.get(key, msg.result)

    # ------------------------------------------------------------------ the learned geometry, kept

    def _load(self) -> None:
        path = self.state_file
        if path is None or not path.exists():
            return
        try:
            state = json.loads(path.read_text())
            why = self.detector.camera.restore(state)
        except (OSError, ValueError, KeyError, TypeError, AttributeError) as exc:
            aside = path.with_name(f"{path.name}.corrupt-{int(time.time())}")
            try:
                path.replace(aside)
            except OSError:
                aside = None
            self.log.warning("falls_geometry_unreadable", file=str(path), error=str(exc),
                             kept_as=str(aside) if aside else None,
                             fix="nothing to do: the geometry is learned again from people; the file was set aside")
            return
        if why is not None:
            self.log.info("falls_geometry_not_restored", file=str(path), reason=why)
            return
        self._saved = json.dumps(self.detector.camera.state(), sort_keys=True)
        self.log.info("falls_geometry_restored", file=str(path), **{
            k: v for k, v in self.detector.geometry.items() if k in ("tilt_deg", "tilt_from", "height_from",
                                                                     "body_s", "standing_s", "floor_weight")})

    def save(self) -> bool:
        """Write the learned geometry when it changed since the last write (atomically, mode 0600). False
        when it could not be written (the error is in the status and logged once per error text)."""
        if self.state_file is None:
            return True
        text = json.dumps(self.detector.camera.state(), sort_keys=True)
        if text == self._saved:
            return True
        path = self.state_file
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            write_private(path, text)
        except OSError as exc:
            if self.save_error != str(exc):
                self.log.warning("falls_geometry_not_saved", file=str(path), error=str(exc),
                                 fix="make the state dir writable (pipeline.state_dir); detection goes on")
            self.save_error = str(exc)
            return False
        self._saved, self.save_error = text, None
        return True

    def start_afresh(self) -> None:
        """Forget every person and every fall in progress (watching resumes after a pause for privacy: what was
        followed before it says nothing of now); what was learned about the camera (its geometry) is kept."""
        if self.people is None:
            return
        old = self.detector
        fresh = FallDetector(old.cfg, old.robot_id, old.fit_frame)
        why = fresh.camera.restore(old.camera.state())
        if why is not None:
            self.log.info("falls_geometry_not_restored", reason=why, when="watching resumed")
        self.people = PeopleFalls(fresh)
        self._save_t = None

    def close(self) -> None:
        """Keep what was learned (on shutdown)."""
        if self.detector is not None:
            self.save()

    def update(self, msg: FitMsg) -> list[FallEvent]:
        """The fall-event messages this frame caused (usually none)."""
        if self.detector is None:
            return []
        cfg = getattr(self.detector, "cfg", None)
        gravity = None
        if cfg is not None and cfg.imu_gravity:
            gravity = getattr(msg.landmarks, "gravity", None)
            if gravity is None:
                gravity = (getattr(msg.landmarks, "extra", None) or {}).get("gravity")
        if gravity is not None:
            try:
                down = _vector3(gravity)
                self.people.each(lambda d: d.set_gravity(down))
            except (TypeError, ValueError) as exc:   # a bad reading: keep the gravity in use, judge the frame
                self.bad_gravity += 1
                if self.bad_gravity <= LOG_FIRST_FAILURES or self.bad_gravity % LOG_FAILURE_EVERY == 0:
                    self.log.warning("imu_gravity_bad", error=str(exc), seq=msg.result.seq, count=self.bad_gravity)
        if cfg is not None and getattr(cfg, "floor_from_depth", False):
            self._depth_floor(msg)
        if self.mount is not None:
            try:
                self._robot_mount(float(msg.result.t))
            except (TypeError, ValueError) as exc:    # the feed checked it: a bug, counted, the frame judged
                self._failed(exc, seq=msg.result.seq)
        try:
            events = self.people.update(_people(msg), float(msg.result.t), msg.result.seq, msg.image_size,
                                        msg.intrinsics)
        except Exception as exc:  # a detector bug must not stop the poses
            self._failed(exc, seq=msg.result.seq)
            return []
        t = float(msg.result.t)
        if self.state_file is not None and (self._save_t is None or t < self._save_t or t - self._save_t >= SAVE_EVERY_S):
            self._save_t = t
            self.save()
        return events

    def tick(self, t: float, without_frames_s: float) -> list[FallEvent]:
        """No frame for ``without_frames_s`` seconds: every person's alarm timer runs on to capture time ``t``
        (:meth:`falls.people.PeopleFalls.tick`); an alarm raised so carries ``without_frames_s``. A detector
        that raises costs this tick's messages only, counted and logged as for a frame."""
        if self.people is None:
            return []
        try:
            events = self.people.tick(t)
        except Exception as exc:  # a detector bug must not stop the stage
            self._failed(exc, tick=round(t, 3))
            return []
        return [replace(e, extra={**e.extra, "without_frames_s": round(float(without_frames_s), 3)})
                for e in events]

    def _failed(self, exc: Exception, **where) -> None:
        """A detector raised (on a frame: ``seq``, or a tick): counted, the stage's error counter up, logged
        (the first LOG_FIRST_FAILURES, then every LOG_FAILURE_EVERY-th)."""
        self.failures += 1
        self._on_error()
        if self.failures <= LOG_FIRST_FAILURES or self.failures % LOG_FAILURE_EVERY == 0:
            self.log.error("fall_detector_failed", error=repr(exc), **where, failures=self.failures)

    def _robot_mount(self, t: float) -> None:
        """Give every detector the robot's camera pose in force at capture time ``t``, or forget it."""
        sample = self.mount.at(t)
        self.mount_in_force = sample is not None
        if sample is None:
            self.people.each(lambda d: d.set_camera_mount(None, None))
            return
        down = np.asarray(sample.down, dtype=float)
        evidence = {"age_s": round(t - sample.t, 3), "valid_s": sample.valid_s, "source": sample.source,
                    "samples": self.mount.received}
        self.people.each(lambda d: d.set_camera_mount(down, sample.height_m, evidence))

    def _depth_floor(self, msg: FitMsg) -> None:
        """Hand the frame's depth floor (or the last one, aged) to the detector; forget it when too old."""
        t = float(msg.result.t)
        field = (getattr(msg.landmarks, "extra", None) or {}).get("floor")
        if field is not None:
            try:
                if not isinstance(field, dict):
                    raise ValueError(f"frame field floor must be an object, got {field!r}")
                tries = {k: field[k] for k in ("tries", "misses", "fit_ms", "prior") if k in field}
                if field.get("down") is not None:
                    down = _vector3(field["down"])
                    height, age = float(field["height_m"]), float(field.get("age_s", 0.0))
                    if not (age >= 0.0 and height > 0.0 and np.all(np.isfinite(down)) and np.any(down)):
                        raise ValueError(f"frame field floor needs a finite non-zero down, height_m > 0 and "
                                         f"age_s >= 0, got {field!r}")
                    evidence = {k: field[k] for k in FLOOR_EVIDENCE if k in field}
                    self._floor = (t - age, down, height, evidence)
                self._floor_tries = tries
            except (TypeError, ValueError, KeyError) as exc:
                self.bad_floor += 1
                if self.bad_floor <= LOG_FIRST_FAILURES or self.bad_floor % LOG_FAILURE_EVERY == 0:
                    self.log.warning("depth_floor_bad", error=str(exc), seq=msg.result.seq, count=self.bad_floor)
        if self._floor is None:
            return
        t_meas, down, height, evidence = self._floor
        age = t - t_meas
        if not 0.0 <= age <= FLOOR_KEEP_S:          # too old (or the clock went back): the other sources
            self._floor = None
            self.people.each(lambda d: d.set_floor_plane(None))
            return
        evidence = {**evidence, **self._floor_tries, "age_s": round(age, 3)}
        self.people.each(lambda d: d.set_floor_plane(down, height, evidence))


def _people(msg: FitMsg) -> list:
    """The frame's people as :meth:`PeopleFalls.update` takes them: its own person first, then the others, each
    with their track id (None without ``people``) and their own landmarks."""
    own = msg.result.extra.get("person")
    out = [(own, msg.result, msg.landmarks.landmarks)]
    if msg.others:
        marks = {p.id: p.landmarks for p in (msg.landmarks.people or ())}
        out += [(r.extra.get("person"), r, marks.get(r.extra.get("person"))) for r in msg.others]
    return out


FLOOR_EVIDENCE = ("tilt_deg", "roll_deg", "inliers", "points", "fraction", "rms_m")


def _vector3(value):
    g = np.asarray(value, dtype=float)
    if g.shape != (3,):
        raise ValueError(f"frame field gravity must be three numbers (camera axes), got {value!r}")
    return g
