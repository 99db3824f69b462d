"""What the browsers are sent: the robot's messages reduced to what the page draws, fanned out to every open
page (one queue per page; a page that does not keep up loses its oldest messages, never blocks the others).

Messages (JSON objects with ``type``): ``pose`` (at most ``pose_rate_hz`` per second: the joints the frame
measured — fitting.measured; an unseen one is absent — in metres, camera axes — x image right, y image down,
z away from the camera — relative to the mid-hip, the mid-hip's camera position when known, and the main joint
angles, null when not measured), ``status`` (with ``floor``: the fall detector's gravity and floor;
``watching``/``not_watching``: whether posed can see at all, with why and since when: the status's ``watch``,
judged by the daemon (the rule of ``hooks.on_watch_lost``), else — an older posed, or one still starting — the
same rule judged here, since when this view saw it (``since_known`` false when it was so already at the first
status); ``restored_open``: falls taken back after a restart whose alarm is still due; ``paused``: while the
status says posed is paused for privacy (``state: paused``, its ``privacy``), who asked and until when — then
``watching`` is false but ``not_watching`` null: a pause someone asked for is said plainly, never as a fault;
``presence``: the status's ``presence`` in words, ``client.presence_note``'s — "last seen 14:02 (12 min ago)",
"in view", while the absence notice runs "not seen for 3 h 10 min — ..." with ``absent`` true — null without one),
``event`` (each fall-event message once per (id, state), with ``restored`` — taken back from the journal
after a restart; ``clock`` when its alarm was raised at once for a stepped clock — and ``without_frames_s`` — an alarm raised with no camera frame for that long — and ``robot``, whose it is), ``acked`` (through this page,
or learned from the robot's journal: acknowledged elsewhere), ``forget`` (events the page no longer lists:
settled and older than its window, ``fall_list``), ``alive``, ``bus`` and ``robot``.
The events held are bounded (``fall_list.FallList``): the page's window and every event not settled.
A hub for every robot (``"*"``) lists every robot's events and keeps each robot's live parts (its last status and
pose, its minute of angles, its liveliness and verdict: newest wins, at most ``MAX_ROBOTS`` robots); a page gets
those of the one robot it shows (``subscribe(robot)``; poses of the others never reach it) and, for every robot,
a ``card`` (``cards``: up or down and since when, watching or why not, paused for privacy, the person's
``presence``, frames per second, its last pose's time and its time zone), the changed ones at most once a tick.
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

from posed.client import dark_note, presence_note
from posed.viz.names import MAIN_ANGLES, evidence_text, short_label
from posed.viz.series import STATE_WORDS
from posed.viz.web.fall_list import KEEP_S, FallList, unix_of

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
MAX_ROBOTS = 100            # robots a hub for every robot holds at most (a card each; beyond: counted, unlisted)
FORGET_GONE_S = KEEP_S      # ... a robot gone this long makes room for a new one when all places are taken
UNLISTED_KEPT = 1000        # robots beyond MAX_ROBOTS counted at most
ROBOT_ID_CHARS = 128        # a robot id longer than this is no robot's (a page's address, a hostile message)


def _num(v) -> float | None:
    try:
        f = float(v)
    except (TypeError, ValueError):
        return None
    return f if math.isfinite(f) else None


def _robot_id(robot) -> bool:
    """Whether ``robot`` can be one robot's id (not ``"*"``, not empty, printable, not too long)."""
    return (isinstance(robot, str) and 0 < len(robot) <= ROBOT_ID_CHARS and robot != EVERY_ROBOT
            and robot.isprintable())


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


class _Live:
    """One robot's live parts as a page shows them (the hub's lock guards it): its last status and pose, the last
    minute of angles, whether it is heard from, and the card last sent to the pages (a hub for every robot)."""

    def __init__(self, robot: str | None, opened: tuple[float, float]) -> None:
        self.robot = robot
        self.opened = opened                    # (monotonic, wall) since when it is waited for
        self.last_pose_at = -math.inf           # the hub's clock: poses thinned to pose_rate_hz
        self.angles: deque = deque()            # (time_unix, {name: deg|None})
        self.status: dict | None = None
        self.pose: dict | None = None
        self.alive: bool | None = None
        self.follow: int | None = None          # several people: the track id the status says is followed
        self.last_seq: int | None = None        # the seq of the last pose that was not another person's
        # whether the robot is heard from: receipt times on this machine (monotonic for ages, wall to show)
        self.heard: tuple[float, float] | None = None       # last status or pose
        self.rise: float | None = None                       # monotonic time liveliness last said up
        self.status_at: float | None = None                  # wall time of the last status received
        self.pose_at: float | None = None                    # ... and of the last pose
        self.pose_unix: float | None = None                  # the last pose's own time (the robot's clock)
        self.status_gaps: deque = deque(maxlen=8)
        self.status_mono: float | None = None
        self.verdict: dict | None = None
        self.not_watching: tuple[str, float, bool] | None = None   # why, since (wall, seen here), whether
        self.saw_watching = False                                   # ... it was seen watching before
        self.card: dict | None = None


_ALL = object()     # a message for every page (not one robot's live part)


class Hub:
    """Thread-safe: the Zenoh callbacks call ``on_*``, the HTTP threads ``subscribe``/``snapshot``."""

    def __init__(self, robot: str, pose_rate_hz: float = 15.0, clock=time.monotonic, *,
                 monotonic=time.monotonic, wall=time.time, max_robots: int = MAX_ROBOTS) -> None:
        self.robot = robot
        self.every = robot == EVERY_ROBOT
        self.min_pose_gap = 1.0 / pose_rate_hz
        self.max_robots = max_robots
        self._clock = clock
        self._lock = threading.Lock()
        self._queues: list[queue.Queue] = []
        self._falls = FallList()
        self._next_prune = -math.inf
        self._bus: dict = {"connected": None, "reason": None, "fix": None}   # None: not known yet
        self.poses_in = 0
        self._mono, self._wall = monotonic, wall
        self._opened = (monotonic(), wall())
        # one robot: its live parts; every robot: each robot's (at most max_robots), and ``_nobody`` for a page
        # that has none selected yet (judged as a robot never heard from), ``_asked`` for one a page selected
        # that is not on the bus (its address kept from before)
        self._one = None if self.every else _Live(robot, self._opened)
        self._robots: dict[str, _Live] = {} if self.every else {robot: self._one}
        self._nobody = _Live(None, self._opened)
        self._asked: dict[str, _Live] = {}
        self._unlisted: set[str] = set()        # robots heard from beyond max_robots (at most UNLISTED_KEPT)
        self._forgotten: list[str] = []         # robots whose card went (gone beyond FORGET_GONE_S), to tell
        self._next_forget = -math.inf

    # ------------------------------------------------------------------ browsers
    def subscribe(self, robot: str | None = None) -> queue.Queue:
        """A page's queue. A page that does not keep up loses its oldest messages; when one of them said more
        than the moment (an event, an acknowledgement, what was forgotten: not a pose), ``resynced`` gives it
        a fresh snapshot instead of what is left, so it never lists what the hub no longer holds nor misses
        a fall. A hub for every robot sends the page the live parts (pose, status, liveliness, verdict) of
        ``robot`` only (``q.robot``; None: :meth:`default_robot`, which may be None: no robot yet)."""
        q: queue.Queue = queue.Queue(QUEUE_LIMIT)
        q.stale = False
        with self._lock:
            if not self.every:
                q.robot = self.robot
            else:
                q.robot = robot if _robot_id(robot) else self._default_robot()
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
        return self.snapshot(getattr(q, "robot", None))

    def unsubscribe(self, q: queue.Queue) -> None:
        with self._lock:
            if q in self._queues:
                self._queues.remove(q)

    def _send(self, msg: dict, robot=_ALL) -> None:
        """To every page; with ``robot`` (a hub for every robot: one robot's live part) to the pages showing it."""
        with self._lock:
            queues = [q for q in self._queues if robot is _ALL or getattr(q, "robot", None) == robot]
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

    def _send_live(self, live: _Live, msg: dict) -> None:
        self._send(msg, live.robot if self.every else _ALL)

    def snapshot(self, robot: str | None = None) -> dict:
        """What a page that opens now needs first; a hub for every robot: the live parts of ``robot`` (None:
        none selected), and ``cards``, one per robot (one robot's hub: None)."""
        with self._lock:
            live = self._live_for_page(robot)
            return {"type": "snapshot", "robot": self.robot, "shown_robot": live.robot, "status": live.status,
                    "pose": live.pose, "angles": [{"time_unix": t, "angles": a} for t, a in live.angles],
                    "events": self._falls.messages(), "acked": self._falls.acked(), "alive": live.alive,
                    "events_keep_days": KEEP_S / 86400,
                    "bus": dict(self._bus), "robot_state": self._judge(live),
                    "state_words": dict(STATE_WORDS),
                    "labels": {n: short_label(n) for n in (*MAIN_ANGLES, *CHART_ANGLES)},
                    "cards": [self._card(x) for _, x in sorted(self._robots.items())] if self.every else None,
                    "unlisted": len(self._unlisted), "max_robots": self.max_robots}

    # ------------------------------------------------------------------ every robot: the cards
    def _live_for_page(self, robot: str | None) -> _Live:
        """The live parts a page of ``robot`` shows (lock held): one robot's hub, its own; every robot, that
        robot's (one not on the bus: a placeholder judged as never heard from), or nobody's."""
        if not self.every:
            return self._one
        if not _robot_id(robot):
            return self._nobody
        live = self._robots.get(robot)
        if live is None:
            live = self._asked.setdefault(robot, _Live(robot, self._opened))
        return live

    def _live(self, robot) -> _Live | None:
        """The robot a message is from (lock held): one robot's hub, its own; every robot, that robot's, held
        from its first message on; None beyond ``max_robots`` (counted in ``unlisted``) unless one held has
        been gone for ``FORGET_GONE_S`` (its card goes: ``forget``)."""
        if not self.every:
            return self._one
        if not _robot_id(robot):
            return None
        live = self._robots.get(robot)
        if live is not None:
            return live
        if len(self._robots) >= self.max_robots and (robot in self._unlisted and self._mono() < self._next_forget
                                                     or not self._forget_one()):
            if len(self._unlisted) < UNLISTED_KEPT:
                self._unlisted.add(robot)
            return None
        live = self._asked.pop(robot, None) or _Live(robot, (self._mono(), self._wall()))
        self._robots[robot] = live
        self._unlisted.discard(robot)
        return live

    def _forget_one(self) -> bool:
        """Make room (lock held): the robot gone the longest, when that is beyond ``FORGET_GONE_S`` (looked for
        at most once a second for robots already unlisted: their every pose comes here)."""
        now_m = self._mono()
        self._next_forget = now_m + 1.0
        gone = [(x.heard[0] if x.heard else x.opened[0], r) for r, x in self._robots.items()
                if self._judge(x)["state"] == "down"]
        if not gone or now_m - min(gone)[0] < FORGET_GONE_S:
            return False
        robot = min(gone)[1]
        del self._robots[robot]
        self._forgotten.append(robot)
        return True

    def _card(self, live: _Live) -> dict:
        """What a robot's card says (lock held): whether it is up (the verdict, since when it is not), its
        liveliness, whether it watches and why not, the person's presence (:func:`presence_of`), its frames per
        second, its last pose's time (its clock, whole seconds) and its time zone."""
        v = self._judge(live)
        st = live.status or {}
        return {"robot": live.robot, "state": v["state"], "why": v["why"],
                "since_unix": None if v["state"] == "up" else v["since_unix"], "alive": live.alive,
                "status": st.get("state"), "watching": st.get("watching"), "not_watching": st.get("not_watching"),
                "paused": st.get("paused"), "fps": st.get("fps"), "time_zone": st.get("time_zone"),
                "presence": st.get("presence"), "unacknowledged": st.get("unacknowledged"),
                "pose_unix": None if live.pose_unix is None else math.floor(live.pose_unix)}

    def default_robot(self) -> str | None:
        with self._lock:
            return self._default_robot()

    def _default_robot(self) -> str | None:
        """The robot a page of every robot shows when none is chosen (lock held): the one with an unacknowledged
        alarm (the earliest such fall), else with an unacknowledged fall event, else the first by id; None with
        no robot (the page's own rule, ``defaultRobot`` in static/app.js, is the same)."""
        falls: dict[str, list[dict]] = {}
        for m in self._falls.messages():
            falls.setdefault(m["id"], []).append(m)
        best = None
        for eid, msgs in falls.items():
            robot = msgs[0].get("robot")
            if robot not in self._robots or self._falls.is_acked(eid):
                continue
            times = [unix_of(m.get("wall_time")) for m in msgs]
            cand = (0 if any(m.get("state") == "alarm" for m in msgs) else 1,
                    min((t for t in times if t is not None), default=math.inf), robot)
            best = cand if best is None or cand < best else best
        if best is not None:
            return best[2]
        return min(self._robots) if self._robots else None

    # ------------------------------------------------------------------ is anyone watching
    def stale_after_s(self, live: _Live | None = None) -> float:
        """How long without a status or a pose the robot counts as silent: ``STALE_PERIODS`` status periods
        (the median gap between the statuses received; the default period before two arrived), at least
        ``STALE_MIN_S``. ``live``: which robot's (default: this hub's robot; every robot: nobody's)."""
        gaps = sorted((live or self._one or self._nobody).status_gaps)
        period = gaps[len(gaps) // 2] if gaps else DEFAULT_STATUS_PERIOD_S
        return max(STALE_MIN_S, STALE_PERIODS * period)

    def _judge(self, live: _Live) -> dict:
        """The verdict on ``live`` (call with the lock held): ``state`` up / waiting / down, ``why`` (bus, gone,
        starting, silent; None when up), ``since_unix`` (when it was last heard from: the last status or pose;
        when never, when this page's server opened — every robot: when it was first heard of),
        ``last_heard_unix``, ``status_at``/``pose_at`` (wall times of the last of each received),
        ``stale_after_s``, ``now_unix`` (this server's clock, so a page can tell ages whatever its own clock
        says)."""
        now_m, now_w = self._mono(), self._wall()
        stale = self.stale_after_s(live)
        heard_m, heard_w = live.heard if live.heard else (None, None)
        since = heard_w if heard_w is not None else live.opened[1]
        grace = max(stale, START_GRACE_S)
        # heard from since its token (re)appeared: what is shown is this run's, not the last one's
        fresh = heard_m is not None and (live.rise is None or heard_m >= live.rise)
        if self._bus.get("connected") is False:
            state, why = "down", "bus"
        elif live.alive is False:
            state, why = "down", "gone"
        elif fresh and now_m - heard_m <= stale:
            state, why = "up", None
        elif heard_m is None and now_m - max(live.opened[0], live.rise or -math.inf) <= grace:
            state, why = "waiting", None
        elif heard_m is not None and not fresh and now_m - live.rise <= grace:
            state, why = "down", "starting"
        else:
            state, why = "down", "silent"
        return {"state": state, "why": why, "since_unix": since, "last_heard_unix": heard_w,
                "status_at": live.status_at, "pose_at": live.pose_at, "stale_after_s": stale,
                "now_unix": now_w}

    def robot_state(self, robot: str | None = None) -> dict:
        """The verdict on this hub's robot (every robot: on ``robot``)."""
        with self._lock:
            return self._judge(self._live_for_page(robot))

    def tick(self) -> None:
        """Judge again against the clock; send the verdict to the pages when it changed (``robot``). Every
        ``PRUNE_EVERY_S`` the fall list drops what the page no longer shows (``forget``). A hub for every robot
        judges each robot, sends each verdict to the pages showing that robot, and the cards that changed to
        every page (``cards``: at most one message a tick, whatever the number of robots)."""
        self._prune()
        out = []
        with self._lock:
            lives = list(self._robots.values())
            if self.every:
                asked = {getattr(q, "robot", None) for q in self._queues}
                for robot in [r for r in self._asked if r not in asked]:
                    del self._asked[robot]
                lives += [self._nobody, *(self._live_for_page(r) for r in asked if r and r not in self._robots)]
            for live in lives:
                verdict = self._judge(live)
                key = (verdict["state"], verdict["why"], verdict["since_unix"] if verdict["state"] == "down" else None)
                old = live.verdict
                if old is not None and (old["state"], old["why"], old["since_unix"] if old["state"] == "down"
                                        else None) == key:
                    continue
                live.verdict = verdict
                out.append((live, {"type": "robot", **verdict, **({"robot": live.robot} if self.every else {})}))
            cards = None
            if self.every:
                changed = []
                for _, live in sorted(self._robots.items()):
                    card = self._card(live)
                    if card != live.card:
                        live.card = card
                        changed.append(card)
                if changed or self._forgotten:
                    cards = {"type": "cards", "cards": changed, "forget": self._forgotten,
                             "unlisted": len(self._unlisted), "max_robots": self.max_robots}
                    self._forgotten = []
        for live, msg in out:
            self._send_live(live, msg)
        if cards is not None:
            self._send(cards)

    def _heard_now(self, live: _Live, what: str | None = None) -> None:
        """A sign of life (call with the lock held)."""
        now_m, now_w = self._mono(), self._wall()
        live.heard = (now_m, now_w)
        if what == "status":
            if live.status_mono is not None:
                live.status_gaps.append(now_m - live.status_mono)
            live.status_mono = now_m
            live.status_at = now_w
        elif what == "pose":
            live.pose_at = now_w

    # ------------------------------------------------------------------ robot
    def on_pose(self, robot: str, result) -> None:
        """A ``fitting.FitResult`` from posed/ROBOT/pose (``extra`` holds ``time_unix`` when sent). Every
        robot: each robot's poses are its own (thinned, kept and sent to the pages showing it)."""
        now = self._clock()
        with self._lock:
            live = self._live(robot)
            if live is None:
                return
            self.poses_in += 1
            self._heard_now(live, "pose")
            live.pose_unix = _num(result.extra.get("time_unix")) or self._wall()
            if not self._is_followed(live, result):
                return
            if now - live.last_pose_at < self.min_pose_gap:
                return
            live.last_pose_at = now
        t_unix = _num(result.extra.get("time_unix")) or time.time()
        # only what this frame measured (fitting.measured): null angles, absent joints otherwise
        angles = {n: _num(result.angle(n)) for n in dict.fromkeys((*MAIN_ANGLES, *CHART_ANGLES))}
        joints = result.measured_joints()
        msg = {"type": "pose", "seq": result.seq, "t": result.t, "time_unix": t_unix, "ok": result.ok,
               "reason": result.reason, "joints": {k: [_num(c) for c in v] for k, v in joints.items()},
               "root": list(result.root_cam_m) if result.root_cam_m is not None else None, "angles": angles,
               "latency_ms": _num((result.extra.get("timing_ms") or {}).get("total")),
               "evidence": evidence_text(result.extra.get("evidence"), result.extra.get("lens")),
               "robot": live.robot}
        with self._lock:
            live.pose = msg
            live.angles.append((t_unix, angles))
            while live.angles and live.angles[0][0] < t_unix - WINDOW_S:
                live.angles.popleft()
        self._send_live(live, msg)

    @staticmethod
    def _is_followed(live: _Live, result) -> bool:
        """Several people (poses with ``person``): the page draws one, the household member the status says is
        followed, else each frame's own person (published first for its seq): the chart never mixes two
        people's angles."""
        person = result.extra.get("person")
        if person is None:
            return True
        if live.follow is not None:
            return person == live.follow
        if result.seq == live.last_seq:
            return False
        live.last_seq = result.seq
        return True

    def on_status(self, robot: str, status) -> None:
        """A ``client.Status``."""
        with self._lock:
            live = self._live(robot)
            if live is None:
                return
        household = ((status.raw or {}).get("falls") or {}).get("household") or {}
        followed = household.get("followed")
        msg = {"type": "status", "robot": robot, "state": status.state, "fps": _num(status.fps),
               "latency_p95_ms": _num(status.latency_p95_ms), "camera": status.camera + dark_note((status.raw or {}).get("camera")), "drops": status.drops,
               "restarts": status.restarts, "unacknowledged": status.unacknowledged_events,
               "time_unix": _num(status.time_unix), "floor": floor_of(status.raw),
               "storage": storage_of(status.raw), "restored_open": restored_open_of(status.raw),
               "time_zone": zone_of(status.raw), "paused": paused_of(status.raw)}
        msg["presence"] = presence_of(status, msg["time_zone"], msg["time_unix"] or self._wall())
        watch = watch_of(status.raw)
        why = not_watching(status.raw) if watch is None else watch[0]
        if msg["paused"] is not None:       # asked for: said as a pause (the page's banner), not as a fault
            why = None
        with self._lock:
            live.follow = followed if isinstance(followed, int) and not isinstance(followed, bool) else None
            if why == "":       # starting or stopping: the judgement so far stands
                why = live.not_watching[0] if live.not_watching else None
            if why is None:
                live.not_watching = None
                live.saw_watching = True
            elif watch is not None:     # the daemon's own judgement: since when is known whenever this view began
                live.not_watching = (why, watch[1], True)
            elif live.not_watching is None:     # since now, or since before the first status heard here
                live.not_watching = (why, self._wall(), live.saw_watching)
            else:
                live.not_watching = (why, *live.not_watching[1:])
            nw = live.not_watching
            msg["watching"] = nw is None and msg["paused"] is None
            msg["not_watching"] = None if nw is None else {"reason": nw[0], "since_unix": nw[1],
                                                            "since_known": nw[2]}
            live.status = msg
            self._heard_now(live, "status")
        self._send_live(live, msg)

    def on_event(self, robot: str, event) -> None:
        """A ``falls.FallEvent`` message; repeats (the daemon republishes until acknowledged) are dropped. Each
        says which robot it is from (``robot``: a page may list several robots' events)."""
        msg = {"type": "event", "id": event.id, "state": event.state, "robot": robot or event.robot,
               "t_detect": event.t_detect, "wall_time": event.wall_time, "confidence": _num(event.confidence),
               "features": list(event.features), **caveats_of(event.extra)}
        with self._lock:
            if not self._falls.add(msg, self._wall()):
                return
            self._live(msg["robot"])       # every robot: a robot heard of by its events has a card too
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
        """The robot's liveliness token (every robot: ``robot``'s; without it, ignored)."""
        with self._lock:
            live = self._live(robot)
            if live is None:
                return
            if alive and live.alive is not True:
                live.rise = self._mono()    # up (or back): its first status is due within a period
            live.alive = alive
        self._send_live(live, {"type": "alive", "alive": alive, **({"robot": live.robot} if self.every else {})})

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
PAUSED_STATE = "paused"     # paused for privacy (posed/ROBOT/privacy/pause): not watching, as asked
BY_CHARS = 64               # who asked for a pause: at most this many characters (the daemon's own limit)
NOT_WATCHING_WORDS = {"blind": "no frame gets through", "waiting_for_camera": "waiting for the camera",
                      "degraded": "a stage is failing", "escalated": "too many restarts",
                      "paused": "paused for privacy",
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
    if state == PAUSED_STATE:
        return NOT_WATCHING_WORDS[PAUSED_STATE]
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


def paused_of(raw) -> dict | None:
    """While the status says posed is paused for privacy (``state: paused``, or its ``privacy.paused`` while
    starting or stopping; a fault during a pause — degraded, escalated — is said as the fault): who asked
    (``by``, None when not said) and since and until when (``since_unix``, ``until_unix``, unix s; None when not
    said); None while it is not paused."""
    if not isinstance(raw, dict):
        return None
    privacy = raw.get("privacy") if isinstance(raw.get("privacy"), dict) else {}
    if raw.get("state") != PAUSED_STATE and not (privacy.get("paused") is True
                                                 and raw.get("state") in UNDECIDED_STATES):
        return None
    by = privacy.get("by")
    by = by if isinstance(by, str) and by and by.isprintable() else None
    return {"by": None if by is None else by[:BY_CHARS], "since_unix": _num(privacy.get("since_unix")),
            "until_unix": _num(privacy.get("until_unix"))}


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


def presence_of(status, zone: str | None, now_unix: float) -> dict | None:
    """A ``client.Status``'s ``presence`` as the page shows it: ``text`` (``client.presence_note``: HH:MM in the
    robot's ``zone``, the age against ``now_unix``, the status's time), ``absent`` (the notice runs: in red),
    ``learning``; None when the status has none (an older posed, the absence notice off, or malformed)."""
    p = status.presence
    if p is None:
        return None
    return {"text": presence_note(p, now_unix, zone), "absent": p.absent, "learning": p.learning,
            "last_seen_unix": p.last_seen_unix}


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

