"""The fall detector: a state machine over the stream of fit results, on capture timestamps only.

States: ``up`` (anything that is not on the floor: standing, walking, sitting on a chair, squatting, ...),
``down`` (an event was raised: the person is on the floor) and ``alarm`` (down for ``alarm_after_s``
without recovering). Messages (``FallEvent``, all with the event's id):

- ``falling``: a fast pelvis descent (``fall_velocity_rel``) reached floor level within ``impact_window_s``
  and stayed there ``confirm_s`` — a fall was seen; or such a descent, then the person lost for
  ``lost_confirm_s`` (feature ``lost_after_descent``: pose extractors lose people lying on the floor); the
  descent profile (``impact_abrupt``, ``supported_phase_before``) sets the confidence, and a braked descent
  from sitting or kneeling (lying down on purpose) raises no ``falling``;
- ``on_floor``: lying at floor level for ``on_floor_confirm_s`` — a slow fall, a person found lying who
  was not seen falling, or (after ``falling``) the person is still down; the time out of sight after lying
  was seen counts too (feature ``lost_while_lying``);
- ``alarm``: down ``alarm_after_s`` after the impact without recovering (the timer runs while the person is
  out of view: losing sight of them never hides the alarm; and without frames: :meth:`FallDetector.tick`);
- ``recovered``: up again (pelvis above ``recover_pelvis_rel``, trunk within ``recover_trunk_deg`` of vertical)
  for ``recover_s``, seen in valid frames (missing frames are no evidence of recovery).

Heights are relative to the person's standing pelvis height (learned while they stand upright with straight
legs; before that, estimated from the fitted leg length). The floor is the configured camera height
(``camera_height_m``), refined from the feet of a person standing upright (``learn_floor``); gravity is the
configured tilt and roll, learned ones (``camera_*_auto``, :mod:`falls.geometry`), the IMU's or the robot's
(:meth:`FallDetector.set_camera_mount`, with the camera's height). Frames that
cannot be judged (no person, failed fit, fewer than three of the shoulders and hips in view) change nothing
but the lost-after-descent rule, the on_floor timer of a person last seen lying, and the alarm timer; gaps up
to ``max_gap_s`` are bridged. See docs/falls.md for every threshold's reason.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from posed.camera_model import Intrinsics
from posed.falls.camera_geometry import CameraGeometry
from posed.falls.config import FallsConfig
from posed.falls.event import FallEvent
from posed.falls.features import ANKLE_OVER_LEG, PELVIS_OVER_LEG, FrameFeatures, measure
from posed.fitting import FitResult

LOST_HORIZON_S = 0.4     # lost while falling: the pelvis would reach floor level this soon at its last speed
# A person judged for less than this before a descent's fast phase is not judged on that descent once lost: a
# landmark track's first frames are placed by the pose detector, not by tracking, and settle over the next few
# (a newcomer's first 3-4 frames are 18-39 px off on the composited scenes, against 6-10 px for the same frames
# tracked: docs/benchmarks.md, "Several people"; the landmark stage trusts a track's left and right only after
# the same 0.5 s, landmarks.sides.SETTLED_S). Their drift is a descent that did not happen.
TRACK_SETTLE_S = 0.5
PROFILE_WINDOW_S = 0.25  # descent profile: speeds over this window (three frames at 10 fps)
# Heights and angles are judged on the median of the last three frames within this much capture time (three
# frames at 10 fps, the rate every other window was set at): one wrong fit among three changes nothing, and
# the median lags a fall by at most 0.1 s at any frame rate. The last three frames alone lagged 0.2 s at 5 fps:
# the pelvis of a falling person is then some 0.25 of its standing height higher than measured.
SMOOTH_WINDOW_S = 0.25
LYING_HYSTERESIS_REL = 0.1   # a person lying stops lying above lying_pelvis_rel (shoulder_rel) + this
LYING_HYSTERESIS_DEG = 15.0  # ... or with the trunk this much nearer vertical than lying_trunk_deg
# A body cannot be under the floor: a pelvis this far below a floor learned from the person's feet (0.5 of its
# standing height, about 0.45 m: three stair steps) means the person is on another level (came down from a
# platform or stairs: the floor was learned on a raised surface), not lying on this floor. The fit's error puts
# a pelvis lying on a learned floor at most ~0.2 below it (the wall camera with a guessed geometry, synthetic);
# the floor is then forgotten and learned again from the feet, and nothing is decided on that frame's height.
# Not applied to a configured floor: a configured height off by some 10 cm, and a fit's scale at the impact,
# put a real fall from a chair 0.7 below it (urfd_14, camera height 0.85 m as labelled).
BELOW_FLOOR_REL = 0.5


@dataclass
class Sample:
    """One judged frame, reduced to what the state machine needs."""

    t: float
    h_rel: float              # pelvis height / standing pelvis height
    shoulders_rel: float      # mid-shoulder height / standing pelvis height
    incl: float               # trunk inclination from vertical (deg)
    aspect: float             # landmark box width / height
    flexion: dict[str, float]


@dataclass
class _Descent:
    t_fast: float             # when the descent first exceeded fall_velocity_rel
    t_onset: float            # when the pelvis began to drop
    v_peak: float             # fastest descent seen (rel/s)
    flex_rate: float = 0.0    # fastest hip/knee flexion since onset (deg/s)


@dataclass
class _Event:
    id: str
    t_onset: float | None
    t_impact: float
    features: tuple[str, ...]
    confidence: float
    geometry: dict = field(default_factory=dict)   # CameraGeometry.used() when the event was raised
    sent: set[str] = field(default_factory=set)
    # an event raised before a restart and continued here (FallDetector.continue_event): the alarm is due at this
    # capture time (its t_impact is on the clock of the run that raised it), and its messages carry ``extra``
    due_t: float | None = None
    extra: dict = field(default_factory=dict)


class FallDetector:
    """``update`` once per frame (every frame, also when there is no person) -> new FallEvent messages.

    ``fit_frame``: how the fit's ``joints_3d`` axes relate to the camera: "camera" (a perspective fit),
    "ray" (a scaled-orthographic fit: axes along the ray through the body) or "auto" (from the result's
    ``projection`` field; orthographic when absent).
    """

    def __init__(self, cfg: FallsConfig, robot_id: str, fit_frame: str = "auto",
                 id_factory: Callable[[], str] = FallEvent.new_id) -> None:
        self.cfg = cfg
        self.robot_id = robot_id
        self.fit_frame = fit_frame
        self._new_id = id_factory
        self.camera = CameraGeometry(cfg)       # gravity, floor, standing height (falls.camera_geometry)
        self._last_smoothed: Sample | None = None
        self._last_v = 0.0
        self._controlled_t: float | None = None   # a controlled descent (lying down on purpose) ended here
        self._samples: deque[Sample] = deque()
        self._last_valid_t: float | None = None
        self._last_t: float | None = None
        self._prev_frame_t: float | None = None
        self.state = "up"
        self._descent: _Descent | None = None
        self._floor_start: float | None = None   # pelvis at floor level since
        self._lying_start: float | None = None   # lying at floor level since
        self._up_start: float | None = None      # up again since (while down)
        self._event: _Event | None = None
        self._last_result: FitResult | None = None
        self.last_sample: Sample | None = None
        self._stand_used: float | None = None     # the standing pelvis height (m) the last sample was judged with
        self._stand_learned = False               # ... and whether it was the learned one (else the leg's estimate)
        self.other_level = 0      # frames whose pelvis was far under the floor in use (BELOW_FLOOR_REL)
        self.last_features: FrameFeatures | None = None   # the last frame's, None when it was not judged
        self.last_camera: Intrinsics | None = None        # the intrinsics it was judged with

    # ------------------------------------------------------------------ calibration inputs

    def set_camera_mount(self, down_camera: np.ndarray | None, height_m: float | None,
                         evidence: dict | None = None) -> bool:
        """The camera's pose from the robot's kinematics (geometry source ``robot``): ``down_camera`` gravity in
        camera axes (x image right, y image down, z forward; any length), ``height_m`` the optical centre above
        the floor (m) or None (gravity only), ``evidence`` shown with it (age_s, source, samples, ...). It comes
        first, ahead of the IMU and the depth floor, for the gravity, and its height first for the floor; while it
        holds, nothing is learned from people about the camera. None forgets it (back to the other sources, with
        what was learned before it). Raises ValueError for a broken pose, changing nothing. True when the gravity
        or floor source changed, which forgets the motion (:meth:`CameraGeometry.set_robot`)."""
        changed = self.camera.set_robot(down_camera, height_m, evidence)
        if changed:
            self._gap()
        return changed

    def set_gravity(self, down_camera: np.ndarray | None) -> None:
        """Gravity from an IMU (e.g. the RealSense accelerometer), a down vector in camera coordinates;
        None returns to the configured (or learned) tilt and roll. A new gravity forgets the motion."""
        if self.camera.set_imu(down_camera):
            self._gap()

    def set_floor_plane(self, down_camera: np.ndarray | None, height_m: float = 0.0,
                        evidence: dict | None = None) -> None:
        """The floor plane measured in the depth image (:meth:`CameraGeometry.set_depth_floor`; None forgets
        it); raises ValueError for a broken one. A new gravity forgets the motion."""
        if self.camera.set_depth_floor(down_camera, height_m, evidence):
            self._gap()

    @property
    def geometry(self) -> dict:
        """The camera geometry in use (:meth:`falls.camera_geometry.CameraGeometry.summary`)."""
        return self.camera.summary()

    @property
    def floor_below_camera(self) -> float | None:
        """The floor's distance below the camera along gravity (m), learned or configured."""
        return self.camera.floor_below_camera

    # ------------------------------------------------------------------ the frame loop

    def update(self, result: FitResult, landmarks: np.ndarray | None, image_size,
               intrinsics: Intrinsics | None = None) -> list[FallEvent]:
        """Feed one frame (capture time ``result.t``); returns the messages it caused (usually none).

        ``intrinsics``: the camera's, in pixels of the landmarks' image; None: a lens of ``camera_hfov_deg``
        across the image's longer side (``Intrinsics.assume``: the lens the fit assumed for the frame).
        """
        t = float(result.t)
        if self._last_t is not None and t < self._last_t:  # a clock step backwards: start over, keep calibration
            self._reset_tracking()
        self._prev_frame_t = self._last_t
        self._last_t = t
        out: list[FallEvent] = []
        camera = intrinsics if intrinsics is not None else \
            Intrinsics.assume(self.cfg.camera_hfov_deg, int(image_size[0]), int(image_size[1]))
        fit_frame = self.fit_frame
        if fit_frame == "auto":  # the fit says which projection it used (orthographic: axes along the ray)
            fit_frame = "camera" if result.extra.get("projection") == "perspective" else "ray"
        geo = self.camera
        self.last_camera = camera
        feats = measure(result, landmarks, image_size, camera, geo.gravity, self.cfg.min_visibility,
                        self.cfg.upright_knee_deg, geo.roll_deg, fit_frame, self.cfg.upright_trunk_deg)
        if feats is not None and feats.straight_body:
            dt = t - self._prev_frame_t if self._prev_frame_t is not None else 0.1
            changed = geo.learn(feats.body_up_c, feats.axis_plane_c, dt)
            if self.state == "up":   # never from a fallen body (a lying one is too far from the gravity in use)
                changed = geo.observe_body_axis(feats.body_up_c, dt, feats.ankles_c,
                                                ANKLE_OVER_LEG * feats.leg_length) or changed
            if changed:
                self._gap()   # heights along the old gravity are not comparable: forget the motion
        if feats is not None and feats.seated_trunk_up_c is not None and self.state == "up":
            dt = t - self._prev_frame_t if self._prev_frame_t is not None else 0.1
            if geo.observe_seated_trunk(feats.seated_trunk_up_c, dt, feats.ankles_c, ANKLE_OVER_LEG * feats.leg_length):
                self._gap()
        sample = self._sample(feats) if feats is not None else None
        self.last_sample = sample
        self.last_features = feats
        if sample is not None:
            self._last_result = result
            if self._last_valid_t is not None and t - self._last_valid_t > self.cfg.max_gap_s:
                self._gap()
            self._last_valid_t = t
            self._samples.append(sample)
            while self._samples and self._samples[0].t < t - 4.0:
                self._samples.popleft()
            out += self._step(sample)
        else:
            out += self._lost(t)
            if not out:
                out += self._lost_lying(t)
            if self._last_valid_t is not None and t - self._last_valid_t > self.cfg.max_gap_s:
                self._gap()
        out += self._timers(t)
        return out

    def tick(self, t: float) -> list[FallEvent]:
        """No frame for a while (the camera blind or unplugged, a recording ended, the pipeline stalled): the
        alarm timer runs on to capture time ``t`` without one; nothing else changes (no frame is no evidence of
        anything, as for a frame without a person). The next frame is judged as usual, whatever its capture
        time: the tick moves no clock of the detector's, so a frame older than ``t`` is no step backwards and an
        alarm raised here is not raised again. A ``t`` before the last frame's changes nothing."""
        if self._last_t is not None and t < self._last_t:
            return []
        return self._timers(t)

    @property
    def event_id(self) -> str | None:
        """The id of the event under way (``down`` or ``alarm``), None when up."""
        return self._event.id if self._event is not None and self.state != "up" else None

    @property
    def judged_up(self) -> bool | None:
        """Whether the last frame's body, as the state machine judged it (the median of the last frames), meets
        the recovery rule: pelvis above ``recover_pelvis_rel`` and trunk within ``recover_trunk_deg``. None
        when the last frame was not judged."""
        s, raw = self._last_smoothed, self.last_sample
        if s is None or raw is None or s.t != raw.t:
            return None
        return s.h_rel > self.cfg.recover_pelvis_rel and s.incl < self.cfg.recover_trunk_deg

    def continue_event(self, event_id: str, t_onset: float | None, t_impact: float | None, due_t: float,
                       features: tuple[str, ...], confidence: float, geometry: dict, sent: set[str],
                       extra: dict) -> None:
        """The event under way is one raised before a restart (the daemon's journal has it): from now on it
        carries that event's id, times, features, confidence and geometry, with ``extra`` in every message;
        its alarm is due at capture time ``due_t``, and ``sent`` are the states already sent (with ``alarm``
        among them the state is ``alarm``). Recovery is judged as for any event. Raises ValueError when no
        event is under way."""
        if self._event is None or self.state == "up":
            raise ValueError("no event under way to continue")
        self._event = _Event(id=event_id, t_onset=t_onset,
                             t_impact=t_impact if t_impact is not None else self._event.t_impact,
                             features=tuple(features), confidence=round(float(confidence), 3),
                             geometry=dict(geometry), sent=set(sent), due_t=float(due_t), extra=dict(extra))
        self.state = "alarm" if "alarm" in sent else "down"

    def _lost(self, t: float) -> list[FallEvent]:
        """Not judged this frame. A fast descent that reached floor level (or came low, or was still on course
        for it, with the trunk tipping over) and then lost the person for ``lost_confirm_s`` is a fall that
        ended out of sight: real pose extractors stop finding people lying on the floor."""
        cfg = self.cfg
        d, s = self._descent, self._last_smoothed
        if self.state != "up" or d is None or s is None or self._last_valid_t is None:
            return []
        raw = self._samples[-1] if self._samples else None
        if raw is not None and self._last_v > cfg.fall_velocity_rel and raw.h_rel < s.h_rel:
            s = raw   # still falling fast in the last frame seen: its height is no outlier, the median lags
        lost_for = t - self._last_valid_t
        if self._last_valid_t - d.t_fast > cfg.impact_window_s or lost_for < cfg.lost_descent_confirm_s - 1e-9:
            return []
        if not self._samples or d.t_fast - self._samples[0].t < TRACK_SETTLE_S - 1e-9:
            return []   # a descent in the first frames of a track: the landmarks were still settling
        tipping = s.incl > cfg.recover_trunk_deg
        # at floor level; or low with the trunk tipping over; or still falling fast with the trunk tipping over
        # and on course to reach floor level within LOST_HORIZON_S (lost in mid-air, the last frames before
        # the impact)
        heading = self._last_v > cfg.fall_velocity_rel and s.h_rel - self._last_v * LOST_HORIZON_S < cfg.floor_pelvis_rel
        low = s.h_rel < cfg.floor_pelvis_rel or (tipping and (s.h_rel < cfg.lying_pelvis_rel or heading))
        if not low:
            return []
        # judged on the descent itself, sooner: the last frames already lying-like, or a descent at twice the fall
        # speed with the trunk tipping over and heading for the floor (lost within a few frames of the impact)
        lying_like = s.incl > cfg.lying_trunk_deg and s.h_rel < cfg.lying_pelvis_rel
        fast = d.v_peak >= 2 * cfg.fall_velocity_rel
        early = lying_like or (fast and tipping)
        if lost_for < cfg.lost_confirm_s - 1e-9 and not early:
            return []
        supporting = self._supporting(s, d.flex_rate)
        feats = ["pelvis_descent_fast", "lost_after_descent"] + supporting
        conf = min(0.85, 0.6 + 0.05 * len(supporting) + (0.1 if fast else 0.0))
        if lost_for < cfg.lost_confirm_s - 1e-9:
            feats.append("judged_on_descent")   # decided before lost_confirm_s: less sure
            conf = min(0.75, conf - 0.1)
        return [self._raise("falling", d.t_onset, self._impact_time(d.t_fast), t, feats, conf)]

    def _lying_event(self, t: float, supporting: list[str], lost: bool = False) -> FallEvent:
        """``on_floor`` for a person lying at floor level since ``_lying_start`` (no fall seen); ``lost``: out of
        sight since they were last seen lying (feature ``lost_while_lying``, less sure)."""
        assert self._lying_start is not None
        onset = self._slow_onset(self._lying_start)
        feats = ["lying_at_floor_level"] + supporting
        conf = min(0.95, 0.55 + 0.1 * (len(feats) - 1))
        if lost:
            feats.append("lost_while_lying")
            conf = min(conf, 0.65)
        if self._controlled_t is not None and t - self._controlled_t <= 5.0:
            feats.append("controlled_descent")   # lay down on purpose, it seems: less sure
            conf = min(conf, 0.5)
        elif self._supported_before(self._lying_start) or (onset is not None and self._supported_before(onset)):
            feats.append("supported_phase_before")   # slowly from sitting or kneeling: less sure
            conf = min(conf, 0.5)
        return self._raise("on_floor", onset, self._lying_start, t, feats, conf)

    def _lost_lying(self, t: float) -> list[FallEvent]:
        """Not judged this frame, and last seen lying at floor level: the ``on_floor`` timer runs on while the
        person is out of sight, as the alarm timer does (pose extractors lose people lying on the floor; missing
        frames are no evidence of getting up). Only after lying was judged on two frames or more (each the
        median of three), so that one wrong fit before a loss raises nothing; only with the last landmark box
        seen wider than tall (``bbox_wide_ratio``): out of sight, the image must agree with the fit that the
        body lies along the floor, since the fit reads someone crouched and curled over on the floor as lying
        (urfd_dev's urfd_42 and urfd_50 end so, their boxes 0.73-0.83 as wide as tall); and only while the gap
        is bridged (``max_gap_s``)."""
        cfg = self.cfg
        s = self._last_smoothed
        if self.state != "up" or self._lying_start is None or self._last_valid_t is None or s is None:
            return []
        if self._last_valid_t <= self._lying_start + 1e-9 or t - self._lying_start < cfg.on_floor_confirm_s - 1e-9:
            return []
        if s.aspect <= cfg.bbox_wide_ratio:
            return []
        return [self._lying_event(t, self._supporting(s, 0.0), lost=True)]

    def _abrupt(self, t_onset: float, t_impact: float) -> bool:
        """The descent profile: did the pelvis still move at half its peak speed or more in the last
        ``PROFILE_WINDOW_S`` before it reached its lowest level? A fall is stopped by the floor; lying down on
        purpose brakes before it."""
        pts = [x for x in self._samples if t_onset - PROFILE_WINDOW_S <= x.t <= t_impact + 1e-9]
        if len(pts) < 3:
            return True   # too few frames to see a braking: no evidence of a controlled descent

        def speed(end: float) -> float | None:
            win = [x for x in pts if end - PROFILE_WINDOW_S - 1e-9 <= x.t <= end + 1e-9]
            if len(win) < 2 or win[-1].t - win[0].t <= 0:
                return None
            return (win[0].h_rel - win[-1].h_rel) / (win[-1].t - win[0].t)

        speeds = [v for v in (speed(x.t) for x in pts) if v is not None]
        v_end = speed(t_impact)
        if not speeds or v_end is None:
            return True
        return v_end >= 0.5 * max(speeds)

    def _supported_before(self, t_onset: float) -> bool:
        """Was the body resting low (sitting on a chair or the floor, kneeling: pelvis below 0.8 of its
        standing height) for most of the 1.5 s (at least 0.5 s of frames) before the descent began? Lying down
        on purpose goes through such a supported phase; a fall from standing does not."""
        before = [x for x in self._samples if t_onset - 1.5 <= x.t < t_onset]
        if len(before) < 3 or before[-1].t - before[0].t < 0.5:
            return False
        low = [x for x in before if x.h_rel < 0.8]
        return len(low) >= 0.8 * len(before)

    def _reset_tracking(self) -> None:
        self._gap()
        self._last_valid_t = None

    def _gap(self) -> None:
        """Lost for longer than max_gap_s: forget motion (velocities, dwell), keep state and event."""
        self._samples.clear()
        self._descent = None
        self._floor_start = self._lying_start = self._up_start = None

    def _sample(self, f: FrameFeatures) -> Sample | None:
        cfg = self.cfg
        geo = self.camera
        # learn the floor and the standing height from a person standing upright with straight legs; the floor
        # also from a person sitting upright (hips and knees flexed 60-120 deg: their feet rest on the floor as
        # a standing person's do) and from one walking upright (the stance foot), along whatever gravity is in
        # use, as for standing feet (feet at or above the camera teach nothing: CameraGeometry.observe_floor)
        upright_trunk = f.trunk_incl_deg < cfg.upright_trunk_deg
        standing = upright_trunk and f.upright_legs
        seated = upright_trunk and f.seated_trunk_up_c is not None
        walking = upright_trunk and f.straight_body
        source, before, scaled = geo.floor_source, geo.floor_below_camera, geo.floor_scaled
        if (standing or seated) and f.below_camera_ankles is not None:
            geo.observe_floor(f.below_camera_ankles + ANKLE_OVER_LEG * f.leg_length, f.ankles_c,
                              ANKLE_OVER_LEG * f.leg_length, standing=standing)
        elif walking and f.below_camera_low_ankle is not None:
            # walking (legs extended, trunk upright, a knee may be bent in its swing): the lower ankle is the
            # stance foot, on the floor
            geo.observe_floor(f.below_camera_low_ankle + ANKLE_OVER_LEG * f.leg_length, f.low_ankle_c,
                              ANKLE_OVER_LEG * f.leg_length)
        floor = geo.floor_below_camera
        # another floor: another source, or a true-metre height now put in the fit's metres (CameraGeometry.fit_scale)
        switched = geo.floor_source != source or geo.floor_scaled != scaled
        delta = floor - before if switched and floor is not None and before is not None else 0.0
        if delta:
            geo.shift_standing_pelvis(delta)   # measured against the old floor
        if floor is None:  # no floor known: judge against the lowest fitted joint instead
            floor = f.below_camera_pelvis + max(max(f.offsets_down.values()), 0.0) + ANKLE_OVER_LEG * f.leg_length
        h_pelvis = floor - f.below_camera_pelvis
        if standing and f.below_camera_ankles is not None:
            geo.observe_standing_pelvis(h_pelvis)
        learned = geo.standing_pelvis()
        stand = max(learned if learned is not None else PELVIS_OVER_LEG * f.leg_length, 0.2)
        if switched and (before is None or geo.floor_below_camera is None):
            self._gap()   # no floor before or now (the lowest joint stood in): nothing to re-express against
        elif (delta or (learned is not None) != self._stand_learned) and self._stand_used is not None:
            # another floor (learned from the feet in place of the configured one), or the learned standing
            # height in place of the leg's estimate: the step between the two is no motion of the body, so the
            # heights seen so far are re-expressed against the new ones (same gravity: a shift and a scale)
            self._reexpress(self._stand_used, stand, delta)
        self._stand_used, self._stand_learned = stand, learned is not None
        shoulders = h_pelvis - 0.5 * (f.offsets_down.get("left_shoulder", 0.0)
                                      + f.offsets_down.get("right_shoulder", 0.0))
        return Sample(t=f.t, h_rel=h_pelvis / stand, shoulders_rel=shoulders / stand, incl=f.trunk_incl_deg,
                      aspect=f.bbox_aspect, flexion=f.flexion)

    def _reexpress(self, stand_old: float, stand_new: float, delta_m: float) -> None:
        """Every height seen (pelvis and shoulders, relative to ``stand_old``) against a floor ``delta_m`` further
        below and relative to ``stand_new``."""
        for x in [*self._samples, *([self._last_smoothed] if self._last_smoothed is not None else [])]:
            x.h_rel = (x.h_rel * stand_old + delta_m) / stand_new
            x.shoulders_rel = (x.shoulders_rel * stand_old + delta_m) / stand_new

    def _descent_velocity(self, t: float) -> float:
        """Downward pelvis speed (rel/s): least-squares slope over the velocity window (or the last two
        samples across a bridged gap)."""
        win = [s for s in self._samples if s.t >= t - self.cfg.velocity_window_s - 1e-9]
        if len(win) < 2 and len(self._samples) >= 2:
            win = list(self._samples)[-2:]
        if len(win) < 2:
            return 0.0
        ts = np.array([s.t for s in win])
        hs = np.array([s.h_rel for s in win])
        dt = ts - ts.mean()
        den = float(dt @ dt)
        return 0.0 if den <= 0 else -float(dt @ (hs - hs.mean())) / den

    def _smoothed(self) -> Sample:
        """The median of the last three samples within ``SMOOTH_WINDOW_S`` of capture time (three at 10 fps and
        above: one bad fit changes nothing; two at 5 fps, whose third would be 0.4 s old)."""
        s = self._samples[-1]
        last = [x for x in list(self._samples)[-3:] if x.t >= s.t - SMOOTH_WINDOW_S]
        return Sample(t=s.t, h_rel=float(np.median([x.h_rel for x in last])),
                      shoulders_rel=float(np.median([x.shoulders_rel for x in last])),
                      incl=float(np.median([x.incl for x in last])),
                      aspect=float(np.median([x.aspect for x in last])), flexion=s.flexion)

    def _flexion_rate(self) -> float:
        if len(self._samples) < 2:
            return 0.0
        a, b = self._samples[-2], self._samples[-1]
        dt = b.t - a.t
        if dt <= 0:
            return 0.0
        return max((abs(b.flexion[k] - a.flexion[k]) / dt for k in b.flexion if k in a.flexion), default=0.0)

    def _step(self, raw: Sample) -> list[FallEvent]:
        cfg = self.cfg
        t = raw.t
        s = self._smoothed()
        if s.h_rel < -BELOW_FLOOR_REL and self.state == "up" and self.camera.used()["floor"] == "learned":
            self.camera.forget_floor()     # another level: the floor in use is not under this person
            self._gap()
            self.other_level += 1
            return []
        self._last_smoothed = s
        v = self._descent_velocity(t)
        self._last_v = v
        at_floor = s.h_rel < cfg.floor_pelvis_rel
        lying = (s.h_rel < cfg.lying_pelvis_rel and s.incl > cfg.lying_trunk_deg
                 and s.shoulders_rel < cfg.lying_shoulder_rel)
        if not lying and self._lying_start is not None:
            # hysteresis: someone lying stays lying until clearly not (the fitted pelvis height of a person
            # lying on their side jitters by +-0.05 rel around lying_pelvis_rel)
            lying = (s.h_rel < cfg.lying_pelvis_rel + LYING_HYSTERESIS_REL
                     and s.incl > cfg.lying_trunk_deg - LYING_HYSTERESIS_DEG
                     and s.shoulders_rel < cfg.lying_shoulder_rel + LYING_HYSTERESIS_REL)
        at_floor = at_floor or lying
        self._floor_start = _since(self._floor_start, t) if at_floor else None
        self._lying_start = _since(self._lying_start, t) if lying else None
        flex_rate = self._flexion_rate()
        out: list[FallEvent] = []

        if self.state == "up":
            d = self._descent
            if d is not None and t - d.t_fast > cfg.impact_window_s and not (
                    self._floor_start is not None and self._floor_start - d.t_fast <= cfg.impact_window_s):
                self._descent = None   # expired before this frame's speed is looked at: a new descent starts now
            if v > cfg.fall_velocity_rel:
                if self._descent is None:
                    self._descent = _Descent(t_fast=t, t_onset=self._onset(t), v_peak=v)
                self._descent.v_peak = max(self._descent.v_peak, v)
            if self._descent is not None:
                self._descent.flex_rate = max(self._descent.flex_rate, flex_rate)
            d = self._descent
            if d is not None and self._floor_start is not None and t - self._floor_start >= cfg.confirm_s - 1e-9:
                t_impact = self._impact_time(d.t_fast)
                supporting = self._supporting(s, d.flex_rate)
                # the descent profile: a fall reaches the floor still fast, lying down on purpose slows first
                abrupt = self._abrupt(d.t_onset, t_impact)
                supported = self._supported_before(d.t_onset)
                if supported and not abrupt:
                    # from sitting or kneeling, slowing down before the floor: lying down on purpose. No
                    # `falling`; lying there is still reported as on_floor (lower confidence) below.
                    self._controlled_t = t
                    self._descent = None
                else:
                    feats = ["pelvis_descent_fast", "pelvis_at_floor_level"] + supporting
                    if abrupt:
                        feats.append("impact_abrupt")
                    if supported:
                        feats.append("supported_phase_before")
                    conf = (0.55 + 0.1 * len(supporting) + (0.1 if d.v_peak > 2 * cfg.fall_velocity_rel else 0.0)
                            + (0.1 if abrupt else 0.0) - (0.15 if supported else 0.0))
                    out.append(self._raise("falling", d.t_onset, t_impact, t, feats, min(0.99, max(0.3, conf))))
            controlled = self._controlled_t is not None and t - self._controlled_t <= 5.0
            if not out and controlled and self._floor_start is not None \
                    and t - self._floor_start >= cfg.on_floor_confirm_s - 1e-9:
                # after a controlled descent, staying at floor level (lying or sitting) is still reported
                feats = ["at_floor_level", "controlled_descent"] + self._supporting(s, flex_rate)
                out.append(self._raise("on_floor", self._slow_onset(self._floor_start), self._floor_start, t, feats,
                                       min(0.5, 0.35 + 0.05 * (len(feats) - 2))))
            if not out and self.state == "up" and self._lying_start is not None \
                    and t - self._lying_start >= cfg.on_floor_confirm_s - 1e-9:
                out.append(self._lying_event(t, self._supporting(s, flex_rate)))
            return out

        # down or alarm
        ev = self._event
        assert ev is not None
        if "on_floor" not in ev.sent and (self._lying_start is not None or self._floor_start is not None):
            since = self._lying_start if self._lying_start is not None else self._floor_start
            if since is not None and t - max(since, ev.t_impact) >= cfg.on_floor_confirm_s - 1e-9:
                out.append(self._message("on_floor", t, ev.features + ("still_on_floor",), ev.confidence))
        up = s.h_rel > cfg.recover_pelvis_rel and s.incl < cfg.recover_trunk_deg
        self._up_start = _since(self._up_start, t) if up else None
        if self._up_start is not None and t - self._up_start >= cfg.recover_s - 1e-9:
            out.append(self._message("recovered", t, ("up_again",), 0.9))
            self.state = "up"
            self._event = None
            self._descent = None
            self._up_start = None
        return out

    def _timers(self, t: float) -> list[FallEvent]:
        ev = self._event
        if ev is None or self.state != "down":
            return []
        due = t - ev.t_impact >= self.cfg.alarm_after_s - 1e-9 if ev.due_t is None else t >= ev.due_t - 1e-9
        if due:
            self.state = "alarm"
            return [self._message("alarm", t, ev.features + ("not_recovered",), max(ev.confidence, 0.9))]
        return []

    # ------------------------------------------------------------------ helpers

    def _onset(self, t_fast: float) -> float:
        """Walk back from the fast sample while the pelvis was higher: when the drop began."""
        samples = [s for s in self._samples if s.t <= t_fast]
        onset = samples[-1].t if samples else t_fast
        for prev, cur in zip(reversed(samples[:-1]), reversed(samples[1:]), strict=False):
            if prev.h_rel < cur.h_rel + 0.01 or t_fast - prev.t > 2.0:
                break
            onset = prev.t
        return onset

    def _slow_onset(self, t_low: float) -> float | None:
        """For a slow fall: the last time before ``t_low`` the pelvis was up; None when never seen up."""
        for s in reversed(self._samples):
            if s.t < t_low and s.h_rel > self.cfg.recover_pelvis_rel:
                return s.t
        return None

    def _impact_time(self, t_fast: float) -> float:
        after = [s for s in self._samples if s.t >= t_fast]
        if not after:
            return t_fast
        low = min(s.h_rel for s in after)
        return next(s.t for s in after if s.h_rel <= low + 0.05)

    def _supporting(self, s: Sample, flex_rate: float) -> list[str]:
        feats = []
        if s.incl > self.cfg.lying_trunk_deg:
            feats.append("trunk_horizontal")
        if s.aspect > self.cfg.bbox_wide_ratio:
            feats.append("bbox_wide")
        if flex_rate > self.cfg.flexion_rate_deg_s:
            feats.append("hip_knee_flexion_fast")
        return feats

    def _raise(self, state: str, t_onset: float | None, t_impact: float, t: float, feats: list[str],
               confidence: float) -> FallEvent:
        self._event = _Event(id=self._new_id(), t_onset=t_onset, t_impact=t_impact, features=tuple(feats),
                             confidence=round(confidence, 3), geometry=self._geometry_used())
        self.state = "down"
        self._descent = None
        self._up_start = None
        return self._message(state, t, tuple(feats), confidence)

    def _geometry_used(self) -> dict:
        """The camera geometry an event is judged with (``CameraGeometry.used``) and ``lens``: ``given`` (the
        frame's intrinsics) or ``assumed`` (``camera_hfov_deg``'s, as the fit assumed it)."""
        assumed = self.last_camera is not None and self.last_camera.assumed
        return {**self.camera.used(), "lens": "assumed" if assumed else "given"}

    def _message(self, state: str, t: float, feats: tuple[str, ...], confidence: float) -> FallEvent:
        ev = self._event
        assert ev is not None
        ev.sent.add(state)
        s = self.last_sample or (self._samples[-1] if self._samples else None)   # lost: the last one seen
        extra = {}
        if s is not None:
            extra = {"pelvis_height_rel": round(s.h_rel, 3), "trunk_inclination_deg": round(s.incl, 1)}
        extra["geometry"] = dict(ev.geometry)
        extra.update(ev.extra)
        return FallEvent(id=ev.id, robot=self.robot_id, state=state, t_onset=ev.t_onset, t_impact=ev.t_impact,
                         t_detect=t, confidence=round(float(confidence), 3), features=feats,
                         pose=self._last_result.to_json() if self._last_result is not None else None,
                         extra=extra)


def _since(start: float | None, t: float) -> float:
    return t if start is None else start

