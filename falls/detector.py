"""The fall detector: a state machine over the stream of fit results, on capture timestamps only.

States: ``up`` (anything that is not on the floor: standing, walking, sitting on a chair, squatting, ...),
``down`` (an event was raised: the person is on the floor) and ``alarm`` (down for ``alarm_after_s``
without recovering). Messages (``FallEvent``, all with the event's id):

- ``falling``: a fast pelvis descent (``fall_velocity_rel``) reached floor level within ``impact_window_s``
  and stayed there ``confirm_s`` — a fall was seen;
- ``on_floor``: lying at floor level for ``on_floor_confirm_s`` — a slow fall, a person found lying who
  was not seen falling, or (after ``falling``) the person is still down;
- ``alarm``: down ``alarm_after_s`` after the impact without recovering (the timer runs while the person is
  out of view: losing sight of them never hides the alarm);
- ``recovered``: up again (pelvis above ``recover_pelvis_rel``, trunk within ``recover_trunk_deg`` of vertical)
  for ``recover_s``, seen in valid frames (missing frames are no evidence of recovery).

Heights are relative to the person's standing pelvis height (learned while they stand upright with straight
legs; before that, estimated from the fitted leg length). The floor is the configured camera height
(``camera_height_m``), refined from the feet of a person standing upright (``learn_floor``). Frames that
cannot be judged (no person, failed fit, shoulders or hips out of view or invisible) change nothing; gaps up
to ``max_gap_s`` are bridged. See docs/falls.md for every threshold's reason.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from camera_model import Intrinsics
from falls.config import FallsConfig
from falls.event import FallEvent
from falls.features import (
    ANKLE_OVER_LEG,
    PELVIS_OVER_LEG,
    FrameFeatures,
    gravity_from_tilt,
    measure,
)
from fitting import FitResult


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
    sent: set[str] = field(default_factory=set)


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
        self._gravity = gravity_from_tilt(cfg.camera_tilt_deg, cfg.camera_roll_deg)
        self._floor_cfg = cfg.camera_height_m if cfg.camera_height_m > 0 else None
        self._floor_learned: float | None = None
        self._floor_weight = 0.0
        self._stand: float | None = None       # standing pelvis height (m), learned
        self._stand_weight = 0.0
        self._samples: deque[Sample] = deque()
        self._last_valid_t: float | None = None
        self._last_t: float | None = None
        self.state = "up"
        self._descent: _Descent | None = None
        self._floor_start: float | None = None   # pelvis at floor level since
        self._lying_start: float | None = None   # lying at floor level since
        self._up_start: float | None = None      # up again since (while down)
        self._event: _Event | None = None
        self._last_result: FitResult | None = None
        self.last_sample: Sample | None = None

    # ------------------------------------------------------------------ calibration inputs

    def set_gravity(self, down_camera: np.ndarray | None) -> None:
        """Gravity from an IMU (e.g. the RealSense accelerometer), a down vector in camera coordinates;
        None returns to the configured tilt and roll."""
        if down_camera is None:
            self._gravity = gravity_from_tilt(self.cfg.camera_tilt_deg, self.cfg.camera_roll_deg)
            return
        g = np.asarray(down_camera, float)
        self._gravity = g / np.linalg.norm(g)

    @property
    def floor_below_camera(self) -> float | None:
        """The floor's distance below the camera along gravity (m), learned or configured."""
        if self._floor_learned is not None and self._floor_weight >= 5:
            return self._floor_learned
        return self._floor_cfg

    # ------------------------------------------------------------------ the frame loop

    def update(self, result: FitResult, landmarks: np.ndarray | None, image_size,
               intrinsics: Intrinsics | None = None) -> list[FallEvent]:
        """Feed one frame (capture time ``result.t``); returns the messages it caused (usually none).

        ``intrinsics``: the camera's, in pixels of the landmarks' image; None: a camera of horizontal field
        of view ``camera_hfov_deg`` (``Intrinsics.from_hfov``).
        """
        t = float(result.t)
        if self._last_t is not None and t < self._last_t:  # a clock step backwards: start over, keep calibration
            self._reset_tracking()
        self._last_t = t
        out: list[FallEvent] = []
        camera = intrinsics if intrinsics is not None else \
            Intrinsics.from_hfov(self.cfg.camera_hfov_deg, int(image_size[0]), int(image_size[1]))
        fit_frame = self.fit_frame
        if fit_frame == "auto":  # the fit says which projection it used (orthographic: axes along the ray)
            fit_frame = "camera" if result.extra.get("projection") == "perspective" else "ray"
        feats = measure(result, landmarks, image_size, camera, self._gravity, self.cfg.min_visibility,
                        self.cfg.upright_knee_deg, self.cfg.camera_roll_deg, fit_frame)
        sample = self._sample(feats) if feats is not None else None
        self.last_sample = sample
        if sample is not None:
            self._last_result = result
            if self._last_valid_t is not None and t - self._last_valid_t > self.cfg.max_gap_s:
                self._gap()
            self._last_valid_t = t
            self._samples.append(sample)
            while self._samples and self._samples[0].t < t - 4.0:
                self._samples.popleft()
            out += self._step(sample)
        elif self._last_valid_t is not None and t - self._last_valid_t > self.cfg.max_gap_s:
            self._gap()
        out += self._timers(t)
        return out

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
        floor = self.floor_below_camera
        # learn the floor and the standing height from a person standing upright with straight legs
        standing = f.trunk_incl_deg < cfg.upright_trunk_deg and f.upright_legs
        if standing and f.below_camera_ankles is not None and cfg.learn_floor:
            obs = f.below_camera_ankles + ANKLE_OVER_LEG * f.leg_length
            self._floor_learned, self._floor_weight = _ema(self._floor_learned, self._floor_weight, obs)
            floor = self.floor_below_camera
        if floor is None:  # no floor known: judge against the lowest fitted joint instead
            floor = f.below_camera_pelvis + max(max(f.offsets_down.values()), 0.0) + ANKLE_OVER_LEG * f.leg_length
        h_pelvis = floor - f.below_camera_pelvis
        if standing and f.below_camera_ankles is not None:
            self._stand, self._stand_weight = _ema(self._stand, self._stand_weight, h_pelvis)
        stand = self._stand if self._stand is not None and self._stand_weight >= 3 else PELVIS_OVER_LEG * f.leg_length
        stand = max(stand, 0.2)
        shoulders = h_pelvis - 0.5 * (f.offsets_down.get("left_shoulder", 0.0)
                                      + f.offsets_down.get("right_shoulder", 0.0))
        return Sample(t=f.t, h_rel=h_pelvis / stand, shoulders_rel=shoulders / stand, incl=f.trunk_incl_deg,
                      aspect=f.bbox_aspect, flexion=f.flexion)

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
        """The median of the last three samples (one bad fit changes nothing)."""
        last = list(self._samples)[-3:]
        s = last[-1]
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
        v = self._descent_velocity(t)
        at_floor = s.h_rel < cfg.floor_pelvis_rel
        lying = (s.h_rel < cfg.lying_pelvis_rel and s.incl > cfg.lying_trunk_deg
                 and s.shoulders_rel < cfg.lying_shoulder_rel)
        at_floor = at_floor or lying
        self._floor_start = _since(self._floor_start, t) if at_floor else None
        self._lying_start = _since(self._lying_start, t) if lying else None
        flex_rate = self._flexion_rate()
        out: list[FallEvent] = []

        if self.state == "up":
            if v > cfg.fall_velocity_rel:
                if self._descent is None:
                    self._descent = _Descent(t_fast=t, t_onset=self._onset(t), v_peak=v)
                self._descent.v_peak = max(self._descent.v_peak, v)
            if self._descent is not None:
                self._descent.flex_rate = max(self._descent.flex_rate, flex_rate)
                reached = self._floor_start is not None and self._floor_start - self._descent.t_fast <= cfg.impact_window_s
                if not reached and t - self._descent.t_fast > cfg.impact_window_s:
                    self._descent = None
            d = self._descent
            if d is not None and self._floor_start is not None and t - self._floor_start >= cfg.confirm_s - 1e-9:
                t_impact = self._impact_time(d.t_fast)
                feats = ["pelvis_descent_fast", "pelvis_at_floor_level"] + self._supporting(s, d.flex_rate)
                conf = min(0.99, 0.6 + 0.1 * (len(feats) - 2) + (0.1 if d.v_peak > 2 * cfg.fall_velocity_rel else 0.0))
                out.append(self._raise("falling", d.t_onset, t_impact, t, feats, conf))
            elif self._lying_start is not None and t - self._lying_start >= cfg.on_floor_confirm_s - 1e-9:
                onset = self._slow_onset(self._lying_start)
                feats = ["lying_at_floor_level"] + self._supporting(s, flex_rate)
                conf = min(0.95, 0.55 + 0.1 * (len(feats) - 1))
                out.append(self._raise("on_floor", onset, self._lying_start, t, feats, conf))
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
        if t - ev.t_impact >= self.cfg.alarm_after_s - 1e-9:
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
                             confidence=round(confidence, 3))
        self.state = "down"
        self._descent = None
        self._up_start = None
        return self._message(state, t, tuple(feats), confidence)

    def _message(self, state: str, t: float, feats: tuple[str, ...], confidence: float) -> FallEvent:
        ev = self._event
        assert ev is not None
        ev.sent.add(state)
        s = self.last_sample
        extra = {}
        if s is not None:
            extra = {"pelvis_height_rel": round(s.h_rel, 3), "trunk_inclination_deg": round(s.incl, 1)}
        return FallEvent(id=ev.id, robot=self.robot_id, state=state, t_onset=ev.t_onset, t_impact=ev.t_impact,
                         t_detect=t, confidence=round(float(confidence), 3), features=feats,
                         pose=self._last_result.to_json() if self._last_result is not None else None,
                         extra=extra)


def _since(start: float | None, t: float) -> float:
    return t if start is None else start


def _ema(value: float | None, weight: float, obs: float, max_weight: float = 30.0) -> tuple[float, float]:
    """Running mean that becomes an exponential average after ``max_weight`` observations."""
    if value is None or not math.isfinite(value):
        return obs, 1.0
    weight = min(weight + 1.0, max_weight)
    return value + (obs - value) / weight, weight
