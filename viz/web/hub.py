"""What the browsers are sent: the robot's messages reduced to what the page draws, fanned out to every open
page (one queue per page; a page that does not keep up loses its oldest messages, never blocks the others).

Messages (JSON objects with ``type``): ``pose`` (at most ``pose_rate_hz`` per second: the joints the frame
measured — fitting.measured; an unseen one is absent — in metres, camera axes — x image right, y image down,
z away from the camera — relative to the mid-hip, the mid-hip's camera position when known, and the main joint
angles, null when not measured), ``status`` (with ``floor``: the fall detector's gravity and floor;
``watching``/``not_watching``: whether posed can see at all, with why and since when: the status's ``watch``,
judged by the daemon (the rule of ``hooks.on_watch_lost``), else — an older posed, or one still starting — the
same rule judged here, since when this view saw it (``since_known`` false when it was so already at the first
status); ``restored_open``: falls taken back after a restart whose alarm is still due),
``event`` (each fall-event message once per (id, state), with ``restored`` — taken back from the journal
after a restart; ``clock`` when its alarm was raised at once for a stepped clock — and ``without_frames_s`` — an alarm raised with no camera frame for that long — and ``robot``, whose it is), ``acked`` (through this page,
or learned from the robot's journal: acknowledged elsewhere), ``forget`` (events the page no longer lists:
settled and older than its window, ``fall_list``), ``alive``, ``bus`` and ``robot``.
The events held are bounded (``fall_list.FallList``): the page's window and every event not settled.
A hub for every robot (``"*"``) lists every robot's events and shows the pose, status and liveliness of one.
With several people in view one person is drawn: the household member the status says is followed, else each
frame's own person. ``snapshot()`` is what a page that opens now needs first: the last status, the last minute
of angles, the events seen, whether the robot is up.

``robot`` is the one verdict the page shows on whether falls are being watched for (``robot_state``): ``up``,
``waiting`` (just opened, nothing heard yet) or ``down`` with why — ``bus`` (this side has no Zenoh session),
``gone`` (the daemon's liveliness token went away: it stopped or died), ``starting`` (its token is back, no
status or pose from the new run yet: what the page holds is the old run's) or ``silent`` (no status and no pose
for ``STALE_PERIODS`` status periods, at least ``STALE_MIN_S``: stuck, or gone without Zenoh noticing) — with
the time it was last heard from. ``tick()`` judges it (the server calls it twice a second) and sends it to every
page when it changed; a snapshot carries it as judged at that moment.
"""

from __future__ import annotations

import math
import queue
import threading
import time
from collections import deque

from posed.viz.names import MAIN_ANGLES, evidence_text, short_label
from posed.viz.series import STATE_WORDS
from posed.viz.web.fall_list import KEEP_S, FallList

CHART_ANGLES = ("theta_hp_l", "theta_hp_r", "theta_kn_l", "theta_kn_r", "theta_tr")
WINDOW_S = 60.0
QUEUE_LIMIT = 256
STALE_PERIODS = 5           # no status and no pose for this many status periods: the robot is silent
STALE_MIN_S = 5.0           # ... and at least this long
DEFAULT_STATUS_PERIOD_S = 1.0   # pipeline.status_period_s's default, until two statuses tell the real one
START_GRACE_S = 12.0        # a page just opened waits this long for a first word before it says "down"
PRUNE_EVERY_S = 60.0        # how often the fall list drops what the page no longer shows (fall_list)
TRANSIENT = ("pose", "status")    # a page that loses one of these is set right by the next (within a second)
EVERY_ROBOT = "*"           # a hub for every robot on the bus: events of all, the live view of one


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

    def __init__(self, robot: str, pose_rate_hz: float = 15.0, clock=time.monotonic, *,
                 monotonic=time.monotonic, wall=time.time) -> None:
        self.robot = robot
        self.min_pose_gap = 1.0 / pose_rate_hz
        self._clock = clock
        self._lock = threading.Lock()
        self._queues: list[queue.Queue] = []
        self._last_pose_at = -math.inf
        self._angles: deque = deque()       # (time_unix, {name: deg|None})
        self._status: dict | None = None
        self._pose: dict | None = None
        self._falls = FallList()
        self._next_prune = -math.inf
        self._shown: str | None = None if robot == EVERY_ROBOT else robot   # whose pose and status are shown
        self._alive: bool | None = None
        self._bus: dict = {"connected": None, "reason": None, "fix": None}   # None: not known yet
        self.poses_in = 0
        self._follow: int | None = None     # several people: the track id the status says is followed
        self._last_seq: int | None = None   # the seq of the last pose that was not another person's
        # whether the robot is heard from: receipt times on this machine (monotonic for ages, wall to show)
        self._mono, self._wall = monotonic, wall
        self._opened = (monotonic(), wall())
        self._heard: tuple[float, float] | None = None          # last status or pose
        self._rise: float | None = None                          # monotonic time liveliness last said up
        self._status_at: float | None = None                     # wall time of the last status received
        self._pose_at: float | None = None                       # ... and of the last pose
        self._status_gaps: deque = deque(maxlen=8)
        self._status_mono: float | None = None
        self._verdict: dict | None = None
        self._not_watching: tuple[str, float, bool] | None = None   # why, since (wall, seen here), whether
        self._saw_watching = False                                   # ... it was seen watching before

    # ------------------------------------------------------------------ browsers
    def subscribe(self) -> queue.Queue:
        """A page's queue. A page that does not keep up loses its oldest messages; when one of them said more
        than the moment (an event, an acknowledgement, what was forgotten: not a pose), ``resynced`` gives it
        a fresh snapshot instead of what is left, so it never lists what the hub no longer holds nor misses
        a fall."""
        q: queue.Queue = queue.Queue(QUEUE_LIMIT)
        q.stale = False
        with self._lock:
            self._queues.append(q)
        return q

    def resynced(self, q: queue.Queue) -> dict | None:
        """A snapshot for a page whose queue lost a message that mattered (emptied: the snapshot has it all);
        None when it lost nothing that matters."""
        if not getattr(q, "stale", False):
            return None
        q.stale = False
        while True:
            try:
                q.get_nowait()
            except queue.Empty:
                break
        return self.snapshot()

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
                        lost = q.get_nowait()
                    except queue.Empty:
                        continue
                    if lost.get("type") not in TRANSIENT:
                        q.stale = True      # an event, an ack...: the page gets a fresh snapshot (resynced)

    def snapshot(self) -> dict:
        with self._lock:
            return {"type": "snapshot", "robot": self.robot, "shown_robot": self._shown, "status": self._status,
                    "pose": self._pose, "angles": [{"time_unix": t, "angles": a} for t, a in self._angles],
                    "events": self._falls.messages(), "acked": self._falls.acked(), "alive": self._alive,
                    "events_keep_days": KEEP_S / 86400,
                    "bus": dict(self._bus), "robot_state": self._judge(),
                    "state_words": dict(STATE_WORDS),
                    "labels": {n: short_label(n) for n in (*MAIN_ANGLES, *CHART_ANGLES)}}

    # ------------------------------------------------------------------ is anyone watching
    def stale_after_s(self) -> float:
        """How long without a status or a pose the robot counts as silent: ``STALE_PERIODS`` status periods
        (the median gap between the statuses received; the default period before two arrived), at least
        ``STALE_MIN_S``."""
        gaps = sorted(self._status_gaps)
        period = gaps[len(gaps) // 2] if gaps else DEFAULT_STATUS_PERIOD_S
        return max(STALE_MIN_S, STALE_PERIODS * period)

    def _judge(self) -> dict:
        """The verdict (call with the lock held): ``state`` up / waiting / down, ``why`` (bus, gone, starting, silent;
        None when up), ``since_unix`` (when it was last heard from: the last status or pose; when never,
        when this page's server opened), ``last_heard_unix``, ``status_at``/``pose_at`` (wall times of the
        last of each received), ``stale_after_s``, ``now_unix`` (this server's clock, so a page can tell
        ages whatever its own clock says)."""
        now_m, now_w = self._mono(), self._wall()
        stale = self.stale_after_s()
        heard_m, heard_w = self._heard if self._heard else (None, None)
        since = heard_w if heard_w is not None else self._opened[1]
        grace = max(stale, START_GRACE_S)
        # heard from since its token (re)appeared: what is shown is this run's, not the last one's
        fresh = heard_m is not None and (self._rise is None or heard_m >= self._rise)
        if self._bus.get("connected") is False:
            state, why = "down", "bus"
        elif self._alive is False:
            state, why = "down", "gone"
        elif fresh and now_m - heard_m <= stale:
            state, why = "up", None
        elif heard_m is None and now_m - max(self._opened[0], self._rise or -math.inf) <= grace:
            state, why = "waiting", None
        elif heard_m is not None and not fresh and now_m - self._rise <= grace:
            state, why = "down", "starting"
        else:
            state, why = "down", "silent"
        return {"state": state, "why": why, "since_unix": since, "last_heard_unix": heard_w,
                "status_at": self._status_at, "pose_at": self._pose_at, "stale_after_s": stale,
                "now_unix": now_w}

    def robot_state(self) -> dict:
        with self._lock:
            return self._judge()

    def tick(self) -> None:
        """Judge again against the clock; send the verdict to the pages when it changed (``robot``). Every
        ``PRUNE_EVERY_S`` the fall list drops what the page no longer shows (``forget``)."""
        self._prune()
        with self._lock:
            verdict = self._judge()
            key = (verdict["state"], verdict["why"], verdict["since_unix"] if verdict["state"] == "down" else None)
            old = self._verdict
            if old is not None and (old["state"], old["why"], old["since_unix"] if old["state"] == "down"
                                    else None) == key:
                return
            self._verdict = verdict
        self._send({"type": "robot", **verdict})

    def _heard_now(self, what: str | None = None) -> None:
        """A sign of life (call with the lock held)."""
        now_m, now_w = self._mono(), self._wall()
        self._heard = (now_m, now_w)
        if what == "status":
            if self._status_mono is not None:
                self._status_gaps.append(now_m - self._status_mono)
            self._status_mono = now_m
            self._status_at = now_w
        elif what == "pose":
            self._pose_at = now_w

    # ------------------------------------------------------------------ robot
    def _is_shown(self, robot: str) -> bool:
        """A hub for every robot shows the live parts (pose, status, liveliness) of one: the first whose status
        came (named on the page); its events are every robot's."""
        if self._shown is None and robot and robot != EVERY_ROBOT:
            self._shown = robot
        return robot == self._shown or self.robot != EVERY_ROBOT

    def on_pose(self, robot: str, result) -> None:
        """A ``fitting.FitResult`` from posed/ROBOT/pose (``extra`` holds ``time_unix`` when sent)."""
        now = self._clock()
        with self._lock:
            if self._shown is None or not self._is_shown(robot):    # every robot: poses once one is chosen
                return
            self.poses_in += 1
            self._heard_now("pose")
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
        with self._lock:
            if not self._is_shown(robot):
                return
        household = ((status.raw or {}).get("falls") or {}).get("household") or {}
        followed = household.get("followed")
        self._follow = followed if isinstance(followed, int) and not isinstance(followed, bool) else None
        msg = {"type": "status", "robot": robot, "state": status.state, "fps": _num(status.fps),
               "latency_p95_ms": _num(status.latency_p95_ms), "camera": status.camera, "drops": status.drops,
               "restarts": status.restarts, "unacknowledged": status.unacknowledged_events,
               "time_unix": _num(status.time_unix), "floor": floor_of(status.raw),
               "storage": storage_of(status.raw), "restored_open": restored_open_of(status.raw),
               "time_zone": zone_of(status.raw)}
        watch = watch_of(status.raw)
        why = not_watching(status.raw) if watch is None else watch[0]
        with self._lock:
            if why == "":       # starting or stopping: the judgement so far stands
                why = self._not_watching[0] if self._not_watching else None
            if why is None:
                self._not_watching = None
                self._saw_watching = True
            elif watch is not None:     # the daemon's own judgement: since when is known whenever this view began
                self._not_watching = (why, watch[1], True)
            elif self._not_watching is None:     # since now, or since before the first status heard here
                self._not_watching = (why, self._wall(), self._saw_watching)
            else:
                self._not_watching = (why, *self._not_watching[1:])
            nw = self._not_watching
            msg["watching"] = nw is None
            msg["not_watching"] = None if nw is None else {"reason": nw[0], "since_unix": nw[1],
                                                            "since_known": nw[2]}
            self._status = msg
            self._heard_now("status")
        self._send(msg)

    def on_event(self, robot: str, event) -> None:
        """A ``falls.FallEvent`` message; repeats (the daemon republishes until acknowledged) are dropped. Each
        says which robot it is from (``robot``: a page may list several robots' events)."""
        msg = {"type": "event", "id": event.id, "state": event.state, "robot": robot or event.robot,
               "t_detect": event.t_detect, "wall_time": event.wall_time, "confidence": _num(event.confidence),
               "features": list(event.features), **caveats_of(event.extra)}
        with self._lock:
            if not self._falls.add(msg, self._wall()):
                return
            full = len(self._falls) > self._falls.max_events
        self._send(msg)
        if full:
            self._prune(force=True)

    def on_acked(self, event_id: str, confirmed: bool) -> None:
        with self._lock:
            if confirmed:
                self._falls.ack(event_id)
        self._send({"type": "acked", "id": event_id, "confirmed": confirmed})

    def on_history(self, stored: list[dict]) -> None:
        """The robot's stored messages (``/api/history``, or the server's own reading): events acknowledged
        elsewhere (another page, ``posed ack``, a phone) become acknowledged here too, and on the pages."""
        with self._lock:
            learned = self._falls.learn(stored)
        for event_id in learned:
            self._send({"type": "acked", "id": event_id, "confirmed": True})
        if learned:
            self._prune(force=True)

    def robot_of(self, event_id: str) -> str | None:
        """The robot an event held here is from (None: not held)."""
        with self._lock:
            return self._falls.robot_of(event_id)

    def span_of(self, event_id: str) -> tuple[float, float] | None:
        """When the event's first and last messages held here were (unix s); None: not known."""
        with self._lock:
            return self._falls.span(event_id)

    def is_acked(self, event_id: str) -> bool:
        with self._lock:
            return self._falls.is_acked(event_id)

    def open_since(self, after: float | None = None) -> float | None:
        """The time (unix s) of the oldest event held here not known to be acknowledged (of those after
        ``after``); None: none."""
        with self._lock:
            return self._falls.open_since(after)

    def held_events(self) -> int:
        with self._lock:
            return len(self._falls)

    def _prune(self, force: bool = False) -> None:
        now = self._mono()
        with self._lock:
            if not force and now < self._next_prune:
                return
            self._next_prune = now + PRUNE_EVERY_S
            gone = self._falls.prune(self._wall())
        if gone.ids:
            self._send({"type": "forget", "ids": list(gone.ids)})

    def on_alive(self, alive: bool, robot: str | None = None) -> None:
        with self._lock:
            if robot is not None and not (robot == self._shown or self.robot != EVERY_ROBOT):
                return
            if alive and self._alive is not True:
                self._rise = self._mono()    # up (or back): its first status is due within a period
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


# why posed is not watching, from its status: the rule of the daemon's hooks.on_watch_lost
# (daemon.outbox.watch_hooks.why_not_watching; tests/viz/test_web_watching.py holds the two together)
NOT_WATCHING_STATES = ("blind", "waiting_for_camera", "degraded", "escalated")
CAMERA_GONE = ("lost", "ended")
UNDECIDED_STATES = ("starting", "stopping")
NOT_WATCHING_WORDS = {"blind": "no frame gets through", "waiting_for_camera": "waiting for the camera",
                      "degraded": "a stage is failing", "escalated": "too many restarts",
                      "lost": "the camera is lost", "ended": "the camera stopped (the recording ended)"}


def not_watching(raw) -> str | None:
    """Why the status says posed is not watching, in words (None: it watches; ``""``: starting or stopping,
    not decided)."""
    if not isinstance(raw, dict):
        return None
    state = raw.get("state")
    camera = raw.get("camera") if isinstance(raw.get("camera"), dict) else {}
    if state in UNDECIDED_STATES:
        return ""
    if state in NOT_WATCHING_STATES:
        blind = raw.get("blind") if isinstance(raw.get("blind"), dict) else {}
        detail = blind.get("reason") or camera.get("error") or ""
        return NOT_WATCHING_WORDS[state] + (f" ({detail})" if detail else "")
    if camera.get("state") in CAMERA_GONE:
        detail = camera.get("error") or ""
        return NOT_WATCHING_WORDS[camera["state"]] + (f" ({detail})" if detail else "")
    return None


def watch_of(raw) -> tuple[str | None, float] | None:
    """The status's ``watch`` (the daemon's own judgement, posed since it has the field): (why not in words, None
    while watching; since when, unix s); None for a status without one (an older posed, or one still starting:
    then :func:`not_watching` judges)."""
    w = raw.get("watch") if isinstance(raw, dict) else None
    if not isinstance(w, dict) or not isinstance(w.get("watching"), bool) or _num(w.get("since_unix")) is None:
        return None
    if w["watching"]:
        return None, _num(w["since_unix"])
    reason = w.get("reason") if isinstance(w.get("reason"), str) and w.get("reason") else "not watching"
    detail = w.get("detail") if isinstance(w.get("detail"), str) else ""
    words = NOT_WATCHING_WORDS.get(reason.removeprefix("camera "), reason)
    return words + (f" ({detail})" if detail else ""), _num(w["since_unix"])


def restored_open_of(raw) -> list[dict]:
    """The falls the daemon took back from its journal after a restart and that are still open (the status's
    ``falls.restored_open``): id, when the alarm is due (unix s), whether it was sent."""
    falls = (raw or {}).get("falls") if isinstance(raw, dict) else None
    items = falls.get("restored_open") if isinstance(falls, dict) else None
    out = []
    for item in items if isinstance(items, list) else ():
        if isinstance(item, dict) and isinstance(item.get("id"), str):
            out.append({"id": item["id"], "due_unix": _num(item.get("due_unix")), "alarm": item.get("alarm") is True})
    return out


def caveats_of(extra: dict) -> dict:
    """A message's caveats as the page shows them, live and in the history: ``restored`` (:func:`restored_of`)
    and ``without_frames_s`` (an alarm raised with no camera frame for that long; None when absent)."""
    return {"restored": restored_of(extra), "without_frames_s": _num(extra.get("without_frames_s"))}


def restored_of(extra: dict) -> dict | None:
    """A message's ``restored`` (taken back after a restart) as the page shows it, None when absent."""
    r = extra.get("restored")
    if not isinstance(r, dict):
        return None
    last = r.get("last_state")
    clock = r.get("clock")
    return {"at_unix": _num(r.get("at_unix")), "due_unix": _num(r.get("due_unix")),
            "last_state": STATE_WORDS.get(last, last) if isinstance(last, str) else None,
            "clock": clock if isinstance(clock, str) else None}


def zone_of(raw) -> str | None:
    """The robot's IANA time zone from its status (``time_zone``), the page's clock; None when not said."""
    zone = (raw or {}).get("time_zone") if isinstance(raw, dict) else None
    return zone if isinstance(zone, str) and 0 < len(zone) <= 64 else None


def storage_of(raw) -> dict | None:
    """The status' ``storage`` (the state directory) as the page shows it: None while all is well."""
    st = (raw or {}).get("storage") if isinstance(raw, dict) else None
    if not isinstance(st, dict) or st.get("state", "ok") == "ok":
        return None
    return {"unstored_events": st.get("unstored_events"), "fallback": st.get("fallback"),
            "reason": st.get("reason"), "fix": st.get("fix")}

