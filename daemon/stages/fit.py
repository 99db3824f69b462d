"""Fitting stage: ``landmarks`` mailbox (LandmarkMsg) -> uDEAS fit -> ``fits`` mailbox (FitMsg).

Warm-up compiles (or loads from the numba cache) the fitting kernels before the stage reports ready. Video
mode: each frame starts from the previous one; the fitter is reset when the stream starts again (sequence
number going back) or after a gap of more than a second of capture time. Frames without a person
(``landmarks`` None) are passed on as ``ok: false`` results, like any other: the fall detector's timers and
its "lost after a descent" rule need them. :class:`StreamFit` is that per-frame logic, shared with the
offline ``posed falls``.

Several people (a frame with ``people``, landmarks.MultiPoseLandmarker): :class:`PeopleFit` fits each person
with a fitter of their own (video mode, learned proportions), keyed by track id: the frame's own person (the
one followed longest) is the FitMsg's ``result``, the others its ``others``, each result with ``person`` (the
track id) in its extra fields. A frame without ``people`` is fitted exactly as before, with no ``person``. A
person unseen for ``FORGET_S`` of capture time is forgotten.

A source without intrinsics (a webcam, a video file, a recording without ``camera``) is fitted through an
assumed lens of ``falls.camera_hfov_deg`` (camera_model.Intrinsics.assume; the fall detector assumes the same
one): in perspective, so a camera looking down shows in the body's axes, but with no ``root_cam_m`` (the
result's ``lens``: assumed). ``fitting.projection: orthographic`` keeps the paper's orthographic fit.

Which way is down (``fitting.vertical: auto``; fitting.vertical): the robot's gravity in force at the frame's
capture time (``falls.camera_mount_from_bus``: the camera poses the publisher received on
``posed/ROBOT/camera/mount``, passed here through the ``mount`` mailbox as
:class:`daemon.stages.mount_samples.MountSamples` and matched to the frame by capture time as the fall detector
matches them), else the frame's own gravity (a RealSense IMU's
or a recording's ``gravity``, when ``falls.imu_gravity`` is on), else the floor plane the landmark stage
measured in the depth image (the frame's ``floor``, its ``down``, when ``falls.floor_from_depth`` is on), else
the camera's configured tilt and roll when ``falls.camera_geometry`` trusts them as measured, else what the
detector learned of the camera from people and kept in the state dir (:class:`KeptDown`: read again every
``SAVE_EVERY_S`` of capture time, as often as the detector writes it), else none (the camera's +y): the order
the fall detector takes them in. The detector's learning reaches the fit only through that file: this stage
runs before it.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np

from posed.camera_model import Intrinsics
from posed.daemon import clock
from posed.daemon.config import paths
from posed.daemon.messages import FitMsg, origin
from posed.daemon.stages.base import StageRuntime
from posed.daemon.stages.fall_watch import SAVE_EVERY_S, geometry_file
from posed.daemon.stages.mount_samples import MountSamples
from posed.fitting import level_frame

RESET_GAP_S = 1.0
LEARNED = ("body", "learned")   # falls.camera_geometry's gravity sources learned from people
FORGET_S = 5.0          # a person of several unseen this long (capture seconds) loses their fitter


class StreamFit:
    """The fit as this stage runs it: video mode, reset when the stream restarts or after a gap."""

    def __init__(self, fitter) -> None:
        self.fitter = fitter
        self.last: tuple[int, float] | None = None

    def fit(self, frame, t_capture: float, image_size, intrinsics, gravity=None):
        """Fit one LandmarkFrame (``landmarks`` None: no person, an ``ok: false`` result); ``gravity``: down in
        the camera's axes, or None (:func:`frame_gravity`)."""
        if self.last is not None and (frame.seq <= self.last[0] or t_capture - self.last[1] > RESET_GAP_S):
            self.fitter.reset()
        self.last = (frame.seq, t_capture)
        return self.fitter.fit(frame.landmarks, frame.seq, t_capture, image_size, mode="video",
                               intrinsics=intrinsics, depth_m=frame.depth_m, world=frame.world, gravity=gravity)


def mount_gravity(falls_cfg) -> np.ndarray | None:
    """Down in the camera's axes from ``falls.camera_tilt_deg`` and ``camera_roll_deg`` when
    ``falls.camera_geometry`` trusts them as measured (falls.camera_geometry.CameraGeometry.tilt_measured),
    else None."""
    from posed.falls.camera_geometry import CameraGeometry

    geometry = CameraGeometry(falls_cfg)
    return np.array(geometry.gravity, dtype=np.float64) if geometry.tilt_measured else None


def kept_gravity(falls_cfg, path: Path) -> np.ndarray | None:
    """The gravity the fall detector learned of this camera from people (their standing bodies, or a learned
    tilt: ``body`` or ``learned``) and kept in its geometry file ``path`` (daemon.stages.fall_watch), as the
    detector takes it back (falls.camera_geometry.CameraGeometry.restore: the same version, learned under the
    same configured values); None otherwise, a missing or unreadable file included (the detector, not this
    stage, reports a bad one)."""
    from posed.falls.camera_geometry import CameraGeometry

    geometry = CameraGeometry(falls_cfg)
    try:
        if geometry.restore(json.loads(path.read_text(encoding="utf-8"))) is not None:
            return None
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return None
    return np.array(geometry.gravity, dtype=np.float64) if geometry.used()["gravity"] in LEARNED else None


class KeptDown:
    """:func:`kept_gravity`, read again every ``every_s`` of capture time (the detector writes it at most every
    ``SAVE_EVERY_S``), or when the clock goes back."""

    def __init__(self, falls_cfg, path: Path, every_s: float = SAVE_EVERY_S) -> None:
        self.falls_cfg, self.path, self.every_s = falls_cfg, Path(path), every_s
        self._t: float | None = None
        self.gravity: np.ndarray | None = None

    def at(self, t: float) -> np.ndarray | None:
        if self._t is None or t < self._t or t - self._t >= self.every_s:
            self._t = t
            self.gravity = kept_gravity(self.falls_cfg, self.path)
        return self.gravity


def frame_gravity(frame, mount: np.ndarray | None, use_imu: bool = True,
                  use_floor: bool = True, robot: np.ndarray | None = None) -> np.ndarray | None:
    """The down a frame is fitted with: ``robot`` (the robot's gravity in force at the frame's capture time,
    :mod:`daemon.stages.mount_samples`) when given, else the frame's own ``gravity`` (an IMU's) when ``use_imu``, else the
    ``down`` of its depth ``floor`` (daemon.stages.depth_floor) when ``use_floor``, each only when it is three
    finite numbers not all 0; else ``mount`` (:func:`mount_gravity`). A malformed one is not this stage's to
    report: the fall detector counts it (``bad_gravity``, ``bad_floor`` in the status)."""
    floor = (getattr(frame, "extra", None) or {}).get("floor") if use_floor else None
    candidates = (robot, getattr(frame, "gravity", None) if use_imu else None,
                  floor.get("down") if isinstance(floor, dict) else None)
    for g in candidates:
        if g is not None:
            try:
                level_frame(g)
                return np.asarray(g, dtype=np.float64)
            except ValueError:
                pass
    return mount


class PersonFitters:
    """Which fitter fits whom in a stream whose frames may carry ``people`` (this stage's :class:`PeopleFit` and
    ``posed fit``): ``main`` fits the frame's own person (whose landmarks are the frame's: the one followed
    longest), and the stream's one person in a frame without ``people``; every other track id has a fitter of
    its own, made by ``make``. When the frame's own person changes, the fitters follow the people. A person
    unseen for ``FORGET_S`` of the stream's time loses theirs."""

    def __init__(self, first, make) -> None:
        self.make = make
        self.main = first
        self.main_id: int | None = None
        self.others: dict[int, object] = {}
        self.seen: dict[int, float] = {}

    def own_person(self, frame, t: float) -> int | None:
        """The track id of ``frame``'s own person (None: not among its ``people``), whose fitter is now
        ``main``."""
        primary = frame.own_person()
        if primary is not None and self.main_id is not None and primary != self.main_id:
            self.others[self.main_id] = self.main             # the one followed longest changed
            self.main = self.others.pop(primary, None) or self.make()
        if primary is not None:
            self.main_id = primary
            self.seen[primary] = t
        return primary

    def of(self, person: int, t: float):
        """The fitter of ``person``, another than the frame's own person, seen at ``t``."""
        fitter = self.others.get(person)
        if fitter is None:
            fitter = self.others[person] = self.make()
        self.seen[person] = t
        return fitter

    def forget(self, t: float) -> None:
        """Drop the fitters of the people unseen for ``FORGET_S`` at ``t``."""
        for pid in [i for i, seen in self.seen.items() if t - seen > FORGET_S and i != self.main_id]:
            self.others.pop(pid, None)
            self.seen.pop(pid, None)

    def reset(self) -> None:
        """Forget every person but keep ``main`` (its state is the caller's to reset)."""
        self.others.clear()
        self.seen.clear()
        self.main_id = None


class PeopleFit:
    """Every person of a frame fitted by a :class:`StreamFit` of their own (see the module doc), the fitters
    assigned by :class:`PersonFitters`."""

    def __init__(self, make_fitter, assumed_hfov_deg: float, mount: np.ndarray | None = None,
                 use_imu: bool = True, use_floor: bool = True) -> None:
        """``assumed_hfov_deg``: the field of view (across the image's longer side) of the lens assumed for
        frames without intrinsics (``falls.camera_hfov_deg``); ``mount``, ``use_imu``, ``use_floor``: which way
        is down (:func:`frame_gravity`)."""
        self.assumed_hfov_deg = assumed_hfov_deg
        self.mount = mount
        self.use_imu = use_imu
        self.use_floor = use_floor
        self.fitters = PersonFitters(StreamFit(make_fitter()), lambda: StreamFit(make_fitter()))

    def fit(self, frame, t_capture: float, image_size, intrinsics, robot: np.ndarray | None = None):
        """(the frame's own person's result, the other people's results); ``robot``: the robot's gravity in force
        at ``t_capture`` (camera axes), or None."""
        if intrinsics is None:
            intrinsics = Intrinsics.assume(self.assumed_hfov_deg, int(image_size[0]), int(image_size[1]))
        gravity = frame_gravity(frame, self.mount, self.use_imu, self.use_floor, robot)
        people = frame.people
        if not people:
            return self.fitters.main.fit(frame, t_capture, image_size, intrinsics, gravity), ()
        primary = self.fitters.own_person(frame, t_capture)
        result = self.fitters.main.fit(frame, t_capture, image_size, intrinsics, gravity)
        if primary is not None:
            result = replace(result, extra={**result.extra, "person": primary})
        out = []
        for p in people:
            if p.id == primary:
                continue
            own = replace(frame, landmarks=p.landmarks, world=p.world, depth_m=p.depth_m, people=None)
            r = self.fitters.of(p.id, t_capture).fit(own, t_capture, image_size, intrinsics, gravity)
            out.append(replace(r, extra={**r.extra, "person": p.id}))
        self.fitters.forget(t_capture)
        return result, tuple(out)

    def reset(self) -> None:
        self.fitters.main.fitter.reset()
        self.fitters.reset()


def people_fit(make_fitter, config) -> PeopleFit:
    """The :class:`PeopleFit` of a daemon configuration (the stage's, ``posed falls``'s and ``posed render``'s)."""
    return PeopleFit(make_fitter, config.falls.camera_hfov_deg, mount_gravity(config.falls), config.falls.imu_gravity,
                     config.falls.floor_from_depth)


def run(rt: StageRuntime) -> None:
    from posed.fitting import CalibrationError, FitResult, Fitter

    with rt.step():
        try:
            fitter = Fitter(rt.config.fitting)
        except CalibrationError as exc:          # checked before start; the file changed since: restarting
            rt.fatal(f"fitting.calibration: {exc}", fix="fix or remove fitting.calibration")   # cannot cure it
        fitter.warmup()
    rt.ready()
    inbox = rt.input
    failures = 0
    spare = [fitter]                       # the warmed-up fitter is the first person's

    def make_fitter():
        return spare.pop() if spare else Fitter(rt.config.fitting)

    people = people_fit(make_fitter, rt.config)
    # no measured mount: what the fall detector learned of the camera from people, kept in the state dir
    kept = None if people.mount is not None else KeptDown(
        rt.config.falls, geometry_file(paths.state_dir(rt.config.pipeline), rt.config.source))
    # the robot's camera poses (falls.camera_mount_from_bus), from the publisher's session: the latest set taken
    mounts_box = rt.mailbox("mount") if rt.config.falls.camera_mount_from_bus else None
    mounts = MountSamples()
    while True:
        rt.beat()
        rt.check_stop()
        msg = inbox.wait(0.1)
        if msg is None:
            continue
        frame = msg.frame
        with rt.step():
            t_in = clock.now()
            others = ()
            try:
                if kept is not None:
                    people.mount = kept.at(msg.t_capture)
                robot = None
                if mounts_box is not None:
                    mounts = mounts_box.take() or mounts
                    sample = mounts.at(msg.t_capture)
                    robot = None if sample is None else np.asarray(sample.down, dtype=np.float64)
                result, others = people.fit(frame, msg.t_capture, msg.image_size, msg.intrinsics, robot)
            except Exception as exc:  # the fitter should never raise; if it does, keep the pipeline going
                failures += 1
                rt.error()
                if failures <= 3 or failures % 100 == 0:
                    rt.log.error("fit_failed", error=repr(exc), seq=frame.seq, failures=failures)
                people.reset()
                result = FitResult.failure(frame.seq, msg.t_capture, f"fit failed: {exc!r}")
            t_out = clock.now()
            rt.send(FitMsg(result, frame, msg.t_capture, msg.image_size,
                           msg.stamps + (("fitting_in", t_in), ("fitting_out", t_out)), msg.intrinsics,
                           msg.t_origin, others), lossless=msg.t_origin is not None)
        rt.done(t_out - t_in, origin(msg), t_out)
