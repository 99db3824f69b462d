"""What the browsers are sent: the robot's messages reduced to what the page draws, fanned out to every open
page (one queue per page; a page that does not keep up loses its oldest messages, never blocks the others).

Messages (JSON objects with ``type``): ``pose`` (at most ``pose_rate_hz`` per second: the joints the frame
measured — fitting.measured; an unseen one is absent — in metres, camera axes — x image right, y image down,
z away from the camera — relative to the mid-hip, the mid-hip's camera position when known, and the main joint
angles, null when not measured), ``status`` (with ``floor``: the fall detector's gravity and floor),
``event`` (each fall-event message once per (id, state)), ``acked``, ``alive``. With several people in view
one person is drawn: the household member the status says is followed, else each frame's own person. ``snapshot()`` is what a page that opens
now needs first: the last status, the last minute of angles, the events seen, whether the robot is up.
"""

from __future__ import annotations

import math
import queue
import threading
import time
from collections import deque

from posed.viz.names import MAIN_ANGLES, evidence_text, short_label

CHART_ANGLES = ("theta_hp_l", "theta_hp_r", "theta_kn_l", "theta_kn_r", "theta_tr")
WINDOW_S = 60.0
QUEUE_LIMIT = 256


def _num(v) -> float | None:
    try:
        f = float(v)
    except (TypeError, ValueError):
        return None
    return f if math.isfinite(f) else None


def floor_of(status_raw: dict) -> dict | None:
    """The floor as the robot's fall detector has it (its status's ``falls.geometry``): ``down``, the unit
    direction of gravity in camera axes (x image right, y down, z away), ``below_camera_m``, the floor's
    distance below the camera along it (None: not known yet), and where each comes from; None without a
    fall detector. ``down`` is falls' ``gravity_from_tilt`` of the tilt and roll it reports (a test holds
    the two formulas together)."""
    geo = ((status_raw or {}).get("falls") or {}).get("geometry")
    if not isinstance(geo, dict):
        return None
    tilt, roll = _num(geo.get("tilt_deg")), _num(geo.get("roll_deg"))
    if tilt is None or roll is None:
        return None
    a, b = math.radians(tilt), math.radians(roll)
    return {"down": [math.sin(b) * math.cos(a), math.cos(b) * math.cos(a), math.sin(a)],
            "below_camera_m": _num(geo.get("floor_below_camera_m")), "tilt_deg": tilt, "roll_deg": roll,
            "tilt_from": geo.get("tilt_from"), "height_from": geo.get("height_from")}


class Hub:
    """Thread-safe: the Zenoh callbacks call ``on_*``, the HTTP threads ``subscribe``/``snapshot``."""

    def __init__(self, robot: str, pose_rate_hz: float = 15.0, clock=time.monotonic) -> None:
        self.robot = robot
        self.min_pose_gap = 1.0 / pose_rate_hz
        self._clock = clock
        self._lock = threading.Lock()
        self._queues: list[queue.Queue] = []
        self._last_pose_at = -math.inf
        self._angles: deque = deque()       # (time_unix, {name: deg|None})
        self._status: dict | None = None
        self._pose: dict | None = None
        self._events: dict[tuple[str, str], dict] = {}
        self._acked: set[str] = set()
        self._alive: bool | None = None
        self._bus: dict = {"connected": None, "reason": None, "fix": None}   # None: not known yet
        self.poses_in = 0
        self._follow: int | None = None     # several people: the track id the status says is followed
        self._last_seq: int | None = None   # the seq of the last pose that was not another person's

    # ------------------------------------------------------------------ browsers
    def subscribe(self) -> queue.Queue:
        q: queue.Queue = queue.Queue(QUEUE_LIMIT)
        with self._lock:
            self._queues.append(q)
        return q

    def unsubscribe(self, q: queue.Queue) -> None:
        with self._lock:
            if q in self._queues:
                self._queues.remove(q)

    def _send(self, msg: dict) -> None:
        with self._lock:
            queues = list(self._queues)
        for q in queues:
            while True:
                try:
                    q.put_nowait(msg)
                    break
                except queue.Full:
                    try:
                        q.get_nowait()
                    except queue.Empty:
                        pass

    def snapshot(self) -> dict:
        with self._lock:
            return {"type": "snapshot", "robot": self.robot, "status": self._status, "pose": self._pose,
                    "angles": [{"time_unix": t, "angles": a} for t, a in self._angles],
                    "events": list(self._events.values()), "acked": sorted(self._acked), "alive": self._alive,
                    "bus": dict(self._bus),
                    "labels": {n: short_label(n) for n in (*MAIN_ANGLES, *CHART_ANGLES)}}

    # ------------------------------------------------------------------ robot
    def on_pose(self, robot: str, result) -> None:
        """A ``fitting.FitResult`` from posed/ROBOT/pose (``extra`` holds ``time_unix`` when sent)."""
        now = self._clock()
        self.poses_in += 1
        if not self._is_followed(result):
            return
        if now - self._last_pose_at < self.min_pose_gap:
            return
        self._last_pose_at = now
        t_unix = _num(result.extra.get("time_unix")) or time.time()
        # only what this frame measured (fitting.measured): null angles, absent joints otherwise
        angles = {n: _num(result.angle(n)) for n in dict.fromkeys((*MAIN_ANGLES, *CHART_ANGLES))}
        joints = result.measured_joints()
        msg = {"type": "pose", "seq": result.seq, "t": result.t, "time_unix": t_unix, "ok": result.ok,
               "reason": result.reason, "joints": {k: [_num(c) for c in v] for k, v in joints.items()},
               "root": list(result.root_cam_m) if result.root_cam_m is not None else None, "angles": angles,
               "latency_ms": _num((result.extra.get("timing_ms") or {}).get("total")),
               "evidence": evidence_text(result.extra.get("evidence"), result.extra.get("lens"))}
        with self._lock:
            self._pose = msg
            self._angles.append((t_unix, angles))
            while self._angles and self._angles[0][0] < t_unix - WINDOW_S:
                self._angles.popleft()
        self._send(msg)

    def _is_followed(self, result) -> bool:
        """Several people (poses with ``person``): the page draws one, the household member the status says is
        followed, else each frame's own person (published first for its seq): the chart never mixes two
        people's angles."""
        person = result.extra.get("person")
        if person is None:
            return True
        if self._follow is not None:
            return person == self._follow
        if result.seq == self._last_seq:
            return False
        self._last_seq = result.seq
        return True

    def on_status(self, robot: str, status) -> None:
        """A ``client.Status``."""
        household = ((status.raw or {}).get("falls") or {}).get("household") or {}
        followed = household.get("followed")
        self._follow = followed if isinstance(followed, int) and not isinstance(followed, bool) else None
        msg = {"type": "status", "state": status.state, "fps": _num(status.fps),
               "latency_p95_ms": _num(status.latency_p95_ms), "camera": status.camera, "drops": status.drops,
               "restarts": status.restarts, "unacknowledged": status.unacknowledged_events,
               "time_unix": _num(status.time_unix), "floor": floor_of(status.raw),
               "storage": storage_of(status.raw)}
        with self._lock:
            self._status = msg
        self._send(msg)

    def on_event(self, robot: str, event) -> None:
        """A ``falls.FallEvent`` message; repeats (the daemon republishes until acknowledged) are dropped."""
        key = (event.id, event.state)
        msg = {"type": "event", "id": event.id, "state": event.state, "t_detect": event.t_detect,
               "wall_time": event.wall_time, "confidence": _num(event.confidence),
               "features": list(event.features)}
        with self._lock:
            if key in self._events:
                return
            self._events[key] = msg
            self._acked.discard(event.id)   # a new state needs its own acknowledgement
        self._send(msg)

    def on_acked(self, event_id: str, confirmed: bool) -> None:
        with self._lock:
            if confirmed:
                self._acked.add(event_id)
        self._send({"type": "acked", "id": event_id, "confirmed": confirmed})

    def on_alive(self, alive: bool) -> None:
        with self._lock:
            self._alive = alive
        self._send({"type": "alive", "alive": alive})

    def on_bus(self, connected: bool, reason: str | None, fix: str | None) -> None:
        """Whether the page's side reaches the robot's bus at all (a page that cannot must say so, never show
        an empty history as if nothing happened); sent to the browsers when it changes."""
        bus = {"connected": connected, "reason": reason, "fix": fix}
        with self._lock:
            if bus == self._bus:
                return
            self._bus = bus
        self._send({"type": "bus", **bus})


def storage_of(raw) -> dict | None:
    """The status' ``storage`` (the state directory) as the page shows it: None while all is well."""
    st = (raw or {}).get("storage") if isinstance(raw, dict) else None
    if not isinstance(st, dict) or st.get("state", "ok") == "ok":
        return None
    return {"unstored_events": st.get("unstored_events"), "fallback": st.get("fallback"),
            "reason": st.get("reason"), "fix": st.get("fix")}

