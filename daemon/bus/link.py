"""The publisher's link to the bus: the process's one Zenoh session, opened with retries, and everything
declared on it (interfaces.md section 4).

* publishers with per-stream QoS: ``pose`` (congestion control DROP, DATA_HIGH, express: never blocks the
  pipeline), ``landmarks`` and ``status`` (DROP), ``events/fall`` (reliable, congestion control BLOCK,
  INTERACTIVE_HIGH: never dropped);
* the liveliness token ``alive``, and ``alive/<instance>`` with a liveliness subscriber to its siblings: another
  daemon with this robot id on the network is said loudly (:mod:`daemon.bus.robot_claim`); the queryables
  ``state`` and ``events/history`` (:mod:`daemon.bus.queries`);
  the subscriber ``events/ack``, whose acknowledgements (:mod:`daemon.bus.acks`) go to the ``on_ack`` callback
  as ``(event id, state or None)``; a payload that is not one is counted (``acks_rejected``) and logged with a
  rate limit (:class:`daemon.proc.throttle.Throttle`), so a flood cannot fill the log;
* with ``on_mount`` (``falls.camera_mount_from_bus``) the subscriber ``camera/mount``: each payload's raw bytes go
  to ``on_mount``, which parses them (:mod:`daemon.stages.mount_feed`); without it, no subscriber;
* with ``on_pause`` the queryable ``privacy/pause``: each query is read (:mod:`daemon.bus.pause_query`) and
  handed to ``on_pause``, whose ``posed.privacy`` message (or refusal) is the reply.

The session is opened after spawn and entered into the stage's ``ExitStack`` (so it is used inside ``with``);
when it cannot be opened (client mode without a router, a busy port) ``try_open`` retries every
``zenoh.reconnect_s`` and everything published meanwhile is dropped, except what the caller keeps (the event
journal). Times are seconds on the monotonic clock.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable

from posed.daemon.bus import acks, pause_query, queries
from posed.daemon.bus.listen_check import ListenPortTaken, taken_listen_problems
from posed.daemon.bus.payloads import dumps
from posed.daemon.bus.robot_claim import RobotIdWatch, instance_name
from posed.daemon.bus.session import ZenohConfigError, describe_open_error, open_session
from posed.daemon.bus.topics import Topics
from posed.daemon.config.sections import ZenohConfig
from posed.daemon.proc.throttle import Throttle

MATCH_POLL_S = 0.5          # how often the events/fall publisher's matching status is read
LINK_POLL_S = 1.0           # how often the routers (and peers) the session reaches are counted
LOG_FAILURE_EVERY = 12      # after the first, every 12th failed attempt to open the session is logged
LISTEN_TAKEN_FATAL_S = 10.0     # a listen port another program still holds after this long stops the daemon (78)


def declare_publishers(session, topics: Topics) -> dict:
    """The four publishers, by stream name, each with its QoS."""
    import zenoh

    json_enc = zenoh.Encoding.APPLICATION_JSON
    drop = zenoh.CongestionControl.DROP
    return {
        "pose": session.declare_publisher(topics.pose, encoding=json_enc, congestion_control=drop,
                                          priority=zenoh.Priority.DATA_HIGH, express=True),
        "landmarks": session.declare_publisher(topics.landmarks, encoding=json_enc, congestion_control=drop),
        "status": session.declare_publisher(topics.status, encoding=json_enc, congestion_control=drop),
        "fall": session.declare_publisher(topics.events_fall, encoding=json_enc,
                                          congestion_control=zenoh.CongestionControl.BLOCK,
                                          priority=zenoh.Priority.INTERACTIVE_HIGH,
                                          reliability=zenoh.Reliability.RELIABLE),
    }


class BusLink:
    """The session and its entities; the stage's loop calls ``try_open`` and the ``put_*`` methods, Zenoh's
    threads call the query and ack handlers.

    ``history(since, until, limit)`` answers ``events/history`` queries; ``on_ack(event_id, state, by)`` is called
    for each acknowledgement (on a Zenoh thread; ``state`` None: the whole event); ``on_mount(payload bytes)`` for
    each message on ``camera/mount`` (on a Zenoh thread; None: not subscribed); ``on_pause(PauseRequest)`` for each
    query on ``privacy/pause`` (on a Zenoh thread; the ``posed.privacy`` reply, or raises
    :class:`daemon.bus.pause_query.PauseRefused`; None: no queryable)."""

    def __init__(self, cfg: ZenohConfig, robot: str, stack: contextlib.ExitStack, log, *,
                 history: queries.HistoryLookup, on_ack: Callable[[str, str | None, str | None], None],
                 on_mount: Callable[[bytes], None] | None = None,
                 on_pause: Callable[[pause_query.PauseRequest], dict] | None = None) -> None:
        self.cfg = cfg
        self.topics = Topics(robot)
        self.latest = queries.LatestState()
        self.log = log
        self._stack = stack             # the session lives in the stage's ``with`` (closed on exit)
        self._history = history
        self._on_ack = on_ack
        self._on_mount = on_mount
        self._on_pause = on_pause
        self.acks_rejected = 0          # payloads on events/ack that were not an acknowledgement
        self._throttle = Throttle()
        self.session = None
        self._pubs: dict = {}
        self._keep: list = []           # token, queryables, subscriber: kept referenced (pitfall 6)
        self._next_open = 0.0
        self._open_failures = 0
        self._error = ""
        self._matching = False
        self._next_match_poll = 0.0
        self._next_link_poll = 0.0
        self._reached = 0               # routers (client mode) or routers and peers seen at the last count
        self._link_seen = False         # reached one at least once since start
        self._taken_since: float | None = None          # when a listen port was first found taken
        self.robot_ids: RobotIdWatch | None = None      # other daemons with this robot id, once the session opened

    @property
    def is_open(self) -> bool:
        return self.session is not None

    # ------------------------------------------------------------------ the session
    def try_open(self, now: float) -> bool:
        """Open the session if it is closed and the retry time has come; True when it opened now.

        Raises ``ZenohConfigError`` when the native config file cannot be used (retrying cannot help)."""
        if self.session is not None or now < self._next_open:
            return False
        try:
            session = open_session(self.cfg)
        except ZenohConfigError:
            raise
        except Exception as exc:        # ZError: unreachable router, busy port
            self._listen_taken(exc, now)
            self._open_failures += 1
            self._next_open = now + self.cfg.reconnect_s
            self._error = describe_open_error(self.cfg, exc)
            if self._open_failures == 1 or self._open_failures % LOG_FAILURE_EVERY == 0:
                self.log.error("zenoh_unavailable", error=self._error, attempts=self._open_failures,
                               retry_in_s=self.cfg.reconnect_s)
            return False
        self.session = self._stack.enter_context(session)
        self._error = ""
        self._taken_since = None
        t = self.topics
        self._pubs = declare_publishers(session, t)
        instance = instance_name(str(session.zid()), pid=os.getppid())     # the supervisor: `posed run`
        self.robot_ids = RobotIdWatch(t.robot, instance, self.log)
        self._keep = [
            session.liveliness().declare_token(t.alive),
            session.liveliness().declare_token(t.daemon(instance)),
            session.liveliness().declare_subscriber(t.daemons, self.robot_ids.on_token, history=True),
            session.declare_queryable(t.state, self._on_state_query, complete=True),
            # "history/**" also matches the bare key: one queryable answers both forms
            session.declare_queryable(f"{t.history}/**", self._on_history_query, complete=True),
            session.declare_subscriber(t.events_ack, self._on_ack_sample),
        ]
        if self._on_mount is not None:
            self._keep.append(session.declare_subscriber(t.camera_mount, self._on_mount_sample))
        if self._on_pause is not None:
            self._keep.append(session.declare_queryable(t.privacy_pause, self._on_pause_query, complete=True))
        self._stack.callback(self.release)      # runs before the session's own exit (last in, first out)
        self._matching = False
        self.log.info("zenoh_open", zid=str(session.zid()), mode=self.cfg.mode,
                      listen=list(self.cfg.listen), connect=list(self.cfg.connect))
        return True

    def _listen_taken(self, exc: Exception, now: float) -> None:
        """A listen port held by another program (two daemons on one port: both started at once, so that
        ``posed run``'s own check found it free) for LISTEN_TAKEN_FATAL_S is a configuration problem: raises
        :class:`ListenPortTaken` naming the holder and the fix, and the daemon stops with 78 instead of running
        on without a bus, heard by nobody."""
        if "Address already in use" not in str(exc):
            self._taken_since = None
            return
        if self._taken_since is None:
            self._taken_since = now
        if now - self._taken_since < LISTEN_TAKEN_FATAL_S:
            return
        problems = taken_listen_problems(self.cfg, wait_s=0.0)
        if problems:
            raise ListenPortTaken("; ".join(problems))

    def release(self) -> None:
        """Undeclare the token (receivers see DELETE on posed/ROBOT/alive), queryables and publishers."""
        for entity in [*self._keep, *self._pubs.values()]:
            try:
                entity.undeclare()
            except Exception:
                pass
        self.forget()

    def forget(self) -> None:
        """Drop the references to the entities (the session's exit undeclares whatever is left)."""
        self._keep.clear()
        self._pubs.clear()

    def status(self) -> dict:
        """The ``zenoh`` part of the status object."""
        out = {"session": "open" if self.session is not None else "retrying", "mode": self.cfg.mode,
               "listen": list(self.cfg.listen), "connect": list(self.cfg.connect), "error": self._error or None}
        if self.robot_ids is not None:
            out["robot_id_conflict"] = self.robot_ids.status()
        if self.session is not None:
            try:
                out["peers"] = len(list(self.session.info.peers_zid()))
                out["routers"] = len(list(self.session.info.routers_zid()))
            except Exception:
                pass
        return out

    def watch_link(self, now: float) -> None:
        """Every LINK_POLL_S, count what the session reaches: the routers in client mode, the routers and peers
        when ``zenoh.connect`` names endpoints in peer mode (a peer listening on its own has nothing to lose).
        Log ``zenoh_link_lost`` (a warning) when the count falls to 0 and ``zenoh_link_back`` when it rises again:
        Zenoh drops what is put meanwhile without an error, so this is the only sign. Fall events are not lost:
        unacknowledged ones are published again when a subscriber appears."""
        if self.session is None or now < self._next_link_poll:
            return
        self._next_link_poll = now + LINK_POLL_S
        if self.robot_ids is not None:
            self.robot_ids.remind(now)
        if self.cfg.mode != "client" and not self.cfg.connect:
            return
        try:
            n = len(list(self.session.info.routers_zid()))
            if self.cfg.mode != "client":
                n += len(list(self.session.info.peers_zid()))
        except Exception:
            return
        what = "router" if self.cfg.mode == "client" else "router or peer"
        if n == 0 and self._reached > 0:
            self.log.warning("zenoh_link_lost", connect=list(self.cfg.connect), mode=self.cfg.mode,
                             error=f"no {what} reachable any more: poses and status go nowhere",
                             fix=f"check that the {what} at {', '.join(self.cfg.connect) or 'zenoh.connect'} runs "
                                 "and is reachable; fall events are kept and published again until acknowledged")
        elif n > 0 and self._reached == 0 and self._link_seen:
            self.log.info("zenoh_link_back", mode=self.cfg.mode, reached=n)
        self._link_seen = self._link_seen or n > 0
        self._reached = n

    # ------------------------------------------------------------------ publishing
    def _put(self, stream: str, obj) -> bool:
        pub = self._pubs.get(stream)
        if pub is None:
            return False
        pub.put(dumps(obj))
        return True

    def put_pose(self, pose: dict) -> bool:
        """Keep ``pose`` for the state queryable and publish it (False: no session, dropped)."""
        self.latest.set_pose(pose)
        return self._put("pose", pose)

    @property
    def wants_landmarks(self) -> bool:
        """The landmarks topic is published (``zenoh.publish_landmarks``) and the session is open."""
        return self.cfg.publish_landmarks and "landmarks" in self._pubs

    def put_landmarks(self, landmarks: dict) -> bool:
        return self._put("landmarks", landmarks)

    def put_status(self, status: dict) -> bool:
        """Keep ``status`` for the state queryable and publish it."""
        self.latest.set_status(status)
        return self._put("status", status)

    def put_event(self, event: dict) -> bool:
        """Publish one fall-event message, reliably (blocks under congestion); False when there is no session."""
        return self._put("fall", event)

    def event_subscriber_appeared(self, now: float) -> bool:
        """Read (every MATCH_POLL_S) whether anyone subscribes to events/fall; True when someone does now and
        nobody did at the last reading (or since the session opened)."""
        pub = self._pubs.get("fall")
        if pub is None or now < self._next_match_poll:
            return False
        self._next_match_poll = now + MATCH_POLL_S
        matching = bool(pub.matching_status.matching)
        appeared = matching and not self._matching
        self._matching = matching
        return appeared

    @property
    def event_subscribed(self) -> bool:
        """Someone subscribed to events/fall at the last reading."""
        return self._matching

    # ------------------------------------------------------------------ Zenoh callbacks (other threads)
    def _on_state_query(self, query) -> None:
        queries.answer_state(query, self.topics.state, self.latest, self.log)

    def _on_history_query(self, query) -> None:
        queries.answer_history(query, self.topics.history, self._history, self.log)

    def _on_pause_query(self, query) -> None:
        pause_query.answer_pause(query, self.topics.privacy_pause, self._on_pause, self.log, self._throttle)

    def _on_mount_sample(self, sample) -> None:
        try:
            payload = sample.payload.to_bytes()
        except Exception as exc:        # never raise into Zenoh's thread
            payload = f"unreadable payload: {type(exc).__name__}".encode()
        self._on_mount(payload)

    def _on_ack_sample(self, sample) -> None:
        try:
            ack = acks.parse_ack_message(sample.payload.to_bytes())
        except acks.BadAck as exc:
            self.acks_rejected += 1
            suppressed = self._throttle.allow("bad_ack")
            if suppressed is not None:
                self.log.warning("bad_ack", error=str(exc), expected=acks.EXPECTED, rejected=self.acks_rejected,
                                 suppressed=suppressed)
            return
        self._on_ack(ack.id, ack.state, ack.by)
