"""Publisher stage: the one process with a Zenoh session (interfaces.md section 4).

Per fit result (``fits`` mailbox): ``posed/ROBOT/pose`` (the fit result JSON plus ``time_unix``,
``image_size`` and ``timing_ms``; congestion control DROP, never blocks the pipeline) and
``posed/ROBOT/landmarks`` (the frame object of interfaces.md section 1 plus ``image_size``); then the fall
detector, whose events go to the journal *before* they are published on ``posed/ROBOT/events/fall``
(reliable, congestion control BLOCK, never dropped) and to the hooks.

Also: ``posed/ROBOT/status`` (the supervisor's status every ``pipeline.status_period_s``, plus the Zenoh
session and the event backlog), the liveliness token ``posed/ROBOT/alive``, the queryables
``posed/ROBOT/state`` (latest pose + status) and ``posed/ROBOT/events/history`` (stored events; parameters
``since``, ``until`` (unix seconds or ISO 8601), ``limit``), and the subscriber ``posed/ROBOT/events/ack``:
a receiver puts an event id there (text, or JSON ``{"id": ...}``) to acknowledge it. Unacknowledged events
are published again when a new subscriber to events/fall appears and every ``zenoh.event_republish_s``.

The session is opened here, after spawn, inside ``with``; when it cannot be opened (client mode without a
router, a busy port) the stage keeps consuming frames, journals events and retries every
``zenoh.reconnect_s``.
"""

from __future__ import annotations

import contextlib
import json
import math
import threading

from daemon import clock
from daemon.bus.session import ZenohConfigError, describe_open_error, open_session
from daemon.bus.topics import Topics
from daemon.messages import origin, timing_ms
from daemon.stages.base import StageRuntime

HISTORY_DEFAULT_LIMIT = 100
HISTORY_MAX_LIMIT = 10000
MATCH_POLL_S = 0.5
MAINTAIN_EVERY_S = 60.0


def dumps(obj) -> str:
    """JSON without NaN/Infinity (not JSON): such numbers become null."""
    try:
        return json.dumps(obj, allow_nan=False)
    except ValueError:
        return json.dumps(_finite(obj), allow_nan=False)


def _finite(obj):
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite(v) for v in obj]
    return obj


class _Shared:
    """What the Zenoh callback threads read: the latest pose and status."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.pose: dict | None = None
        self.status: dict | None = None


def pose_message(msg, now: float) -> dict:
    """The pose topic's JSON object for one FitMsg (interfaces.md section 2 plus added fields)."""
    out = msg.result.to_json()
    out.setdefault("time_unix", round(clock.wall_from_monotonic(msg.t_capture), 4))
    out.setdefault("image_size", list(msg.image_size))
    out.setdefault("timing_ms", timing_ms(msg.stamps, origin(msg), now))
    return out


def landmarks_message(msg) -> dict:
    out = msg.landmarks.to_json()
    out["image_size"] = list(msg.image_size)
    return out


def parse_history_parameters(params) -> tuple[float | None, float | None, int]:
    """since/until (unix seconds or ISO 8601 / relative forms) and limit from a query's parameters."""
    from daemon.timeparse import parse_time

    def get(key):
        v = params.get(key) if params is not None else None
        return v if v not in (None, "") else None

    since, until = get("since"), get("until")
    limit = get("limit")
    try:
        n = HISTORY_DEFAULT_LIMIT if limit is None else int(limit)
    except ValueError:
        raise ValueError(f"limit={limit!r} is not an integer") from None
    if not 0 <= n <= HISTORY_MAX_LIMIT:
        raise ValueError(f"limit={n} is outside 0..{HISTORY_MAX_LIMIT}")
    return (parse_time(since) if since is not None else None,
            parse_time(until) if until is not None else None, n)


class Publisher:
    """The publisher's state; ``serve(rt)`` runs the loop."""

    def __init__(self, rt: StageRuntime, stack: contextlib.ExitStack) -> None:
        from daemon.config import paths
        from daemon.history.store import AngleHistory
        from daemon.outbox.hooks import HookRunner
        from daemon.outbox.journal import EventJournal
        from falls.detector import FallDetector

        self.rt = rt
        self._stack = stack             # the session lives in the stage's ``with`` (closed on exit)
        cfg = rt.config
        self.cfg = cfg
        self.topics = Topics(cfg.robot_id)
        self.shared = _Shared()
        self.detector = FallDetector(cfg.falls, cfg.robot_id) if cfg.falls.enabled else None
        self.journal = EventJournal(paths.events_path(cfg.pipeline))
        self.hooks = HookRunner(cfg.hooks)
        self.history = AngleHistory(paths.history_path(cfg.pipeline), cfg.falls) \
            if cfg.falls.history_enabled else None
        self.session = None
        self._pubs: dict = {}
        self._keep: list = []           # token, queryables, subscribers: kept referenced (pitfall 6)
        self._next_open = 0.0
        self._open_failures = 0
        self._session_error = ""
        self._matching = False
        self._next_match_poll = 0.0
        self._next_republish = clock.now() + cfg.zenoh.event_republish_s
        self._next_maintain = clock.now() + MAINTAIN_EVERY_S
        self.published = 0
        self.events_published = 0
        self._detector_errors = 0

    # ------------------------------------------------------------------ session
    def try_open(self, now: float) -> None:
        if self.session is not None or now < self._next_open:
            return
        import zenoh

        zcfg = self.cfg.zenoh
        try:
            session = open_session(zcfg)
        except ZenohConfigError as exc:
            self.rt.fatal(str(exc), fix="fix zenoh.config_file")
        except Exception as exc:  # ZError: unreachable router, busy port
            self._open_failures += 1
            self._next_open = now + zcfg.reconnect_s
            self._session_error = describe_open_error(zcfg, exc)
            if self._open_failures == 1 or self._open_failures % 12 == 0:
                self.rt.log.error("zenoh_unavailable", error=self._session_error, attempts=self._open_failures,
                                  retry_in_s=zcfg.reconnect_s)
            return
        self.session = self._stack.enter_context(session)
        self._session_error = ""
        t = self.topics
        json_enc = zenoh.Encoding.APPLICATION_JSON
        drop = zenoh.CongestionControl.DROP
        self._pubs = {
            "pose": session.declare_publisher(t.pose, encoding=json_enc, congestion_control=drop,
                                              priority=zenoh.Priority.DATA_HIGH, express=True),
            "landmarks": session.declare_publisher(t.landmarks, encoding=json_enc, congestion_control=drop),
            "status": session.declare_publisher(t.status, encoding=json_enc, congestion_control=drop),
            "fall": session.declare_publisher(t.events_fall, encoding=json_enc,
                                              congestion_control=zenoh.CongestionControl.BLOCK,
                                              priority=zenoh.Priority.INTERACTIVE_HIGH,
                                              reliability=zenoh.Reliability.RELIABLE),
        }
        self._keep = [
            session.liveliness().declare_token(t.alive),
            session.declare_queryable(t.state, self._on_state_query, complete=True),
            # "history/**" also matches the bare key: one queryable answers both forms
            session.declare_queryable(f"{t.history}/**", self._on_history_query, complete=True),
            session.declare_subscriber(t.events_ack, self._on_ack),
        ]
        self._stack.callback(self._release)     # runs before the session's own exit (last in, first out)
        self._matching = False
        self.rt.log.info("zenoh_open", zid=str(session.zid()), mode=self.cfg.zenoh.mode,
                         listen=list(self.cfg.zenoh.listen), connect=list(self.cfg.zenoh.connect))
        self.publish_events(self.journal.unpublished(), "unpublished")

    def _release(self) -> None:
        """Undeclare the token (receivers see DELETE on posed/ROBOT/alive), queryables and publishers."""
        for entity in [*self._keep, *self._pubs.values()]:
            try:
                entity.undeclare()
            except Exception:
                pass
        self._keep.clear()
        self._pubs.clear()

    def close(self) -> None:
        """Close everything but the session (the ``with`` around the stage closes it)."""
        self._keep.clear()
        self._pubs.clear()
        self.hooks.close(timeout=1.0)
        if self.history is not None:
            self.history.close()
        self.journal.close()

    # ------------------------------------------------------------------ per frame
    def handle(self, msg) -> None:
        now = clock.now()
        pose = pose_message(msg, now)
        with self.shared.lock:
            self.shared.pose = pose
        pub = self._pubs.get("pose")
        if pub is not None:
            pub.put(dumps(pose))
            if self.cfg.zenoh.publish_landmarks:
                self._pubs["landmarks"].put(dumps(landmarks_message(msg)))
        self.published += 1
        if self.detector is not None:
            lms = msg.landmarks.landmarks
            try:
                events = self.detector.update(msg.result, lms, msg.image_size, msg.intrinsics)
            except Exception as exc:  # a detector bug must not stop the poses
                events = []
                self._detector_errors += 1
                self.rt.error()
                if self._detector_errors <= 3 or self._detector_errors % 100 == 0:
                    self.rt.log.error("fall_detector_failed", error=repr(exc), seq=msg.result.seq,
                                      failures=self._detector_errors)
            for event in events:
                stored = self.journal.append(event)          # on disk before anyone hears of it
                self.rt.log.info("fall_event", id=stored.id, state=stored.state, t_detect=stored.t_detect,
                                 confidence=round(stored.confidence, 3), features=list(stored.features))
                self.publish_events([stored], "new")
                self.hooks.submit(stored)
        if self.history is not None:
            self.history.add(msg.result, clock.wall_from_monotonic(msg.t_capture))

    def publish_events(self, events, why: str) -> int:
        pub = self._pubs.get("fall")
        if pub is None or not events:
            return 0
        for event in events:
            pub.put(dumps(event.to_json()))
            self.journal.mark_published(event.id, event.state)
            self.events_published += 1
        if why != "new":
            self.rt.log.info("fall_events_republished", count=len(events), reason=why)
        return len(events)

    # ------------------------------------------------------------------ periodic
    def periodic(self, now: float) -> None:
        status = self.rt.mailbox("status").take()
        if status is not None:
            self.publish_status(status)
        pub = self._pubs.get("fall")
        if pub is not None and now >= self._next_match_poll:
            self._next_match_poll = now + MATCH_POLL_S
            matching = bool(pub.matching_status.matching)
            if matching and not self._matching:
                self.publish_events(self.journal.unacknowledged(), "subscriber appeared")
                self._next_republish = now + self.cfg.zenoh.event_republish_s
            self._matching = matching
        if now >= self._next_republish:
            self._next_republish = now + self.cfg.zenoh.event_republish_s
            self.journal.retry()
            if self._matching:
                self.publish_events(self.journal.unacknowledged(), "period")
        if now >= self._next_maintain:
            self._next_maintain = now + MAINTAIN_EVERY_S
            if self.history is not None:
                try:
                    self.history.maintain()
                except Exception as exc:
                    self.rt.log.error("history_maintenance_failed", error=repr(exc))

    def publish_status(self, status: dict) -> None:
        status = dict(status)
        status["zenoh"] = {"session": "open" if self.session is not None else "retrying",
                           "mode": self.cfg.zenoh.mode, "listen": list(self.cfg.zenoh.listen),
                           "connect": list(self.cfg.zenoh.connect), "error": self._session_error or None}
        if self.session is not None:
            try:
                status["zenoh"]["peers"] = len(list(self.session.info.peers_zid()))
                status["zenoh"]["routers"] = len(list(self.session.info.routers_zid()))
            except Exception:
                pass
        status["events"] = {"unacknowledged": len(self.journal.unacknowledged()),
                            "journal": "ok" if self.journal.healthy else (self.journal.last_error or "degraded"),
                            "published": self.events_published}
        with self.shared.lock:
            self.shared.status = status
        pub = self._pubs.get("status")
        if pub is not None:
            pub.put(dumps(status))

    # ------------------------------------------------------------------ Zenoh callbacks (other threads)
    def _on_state_query(self, query) -> None:
        with self.shared.lock:
            body = {"pose": self.shared.pose, "status": self.shared.status}
        try:
            query.reply(self.topics.state, dumps(body))
        except Exception as exc:
            self.rt.log.warning("state_query_failed", error=repr(exc))

    def _on_history_query(self, query) -> None:
        """One reply per stored message, each on its own key ``.../events/history/<id>/<state>`` (so that
        consolidation cannot merge them); a query on the bare key (which cannot accept other keys) gets one
        reply holding the list."""
        base = self.topics.history
        try:
            since, until, limit = parse_history_parameters(query.parameters)
        except ValueError as exc:
            query.reply_err(json.dumps({"error": str(exc), "usage": "since, until: unix seconds or ISO 8601 "
                                                                   "(also 2h, 7d, today); limit: integer"}))
            return
        try:
            stored = self.journal.query(since, until, limit)
            if str(query.key_expr) == base:
                query.reply(base, json.dumps({"events": [s.to_json() for s in stored], "count": len(stored)}))
            else:
                for s in stored:
                    query.reply(f"{base}/{s.event.id}/{s.event.state}", json.dumps(s.to_json()))
        except Exception as exc:
            self.rt.log.warning("history_query_failed", error=repr(exc))
            try:
                query.reply_err(json.dumps({"error": repr(exc)}))
            except Exception:
                pass

    def _on_ack(self, sample) -> None:
        raw = sample.payload.to_string().strip()
        event_id = raw
        if raw.startswith("{"):
            try:
                event_id = str(json.loads(raw).get("id", ""))
            except (ValueError, AttributeError):
                event_id = ""
        if not event_id:
            self.rt.log.warning("bad_ack", payload=raw[:200], expected="an event id, or JSON {\"id\": ...}")
            return
        n = self.journal.acknowledge(event_id)
        self.rt.log.info("fall_event_acknowledged", id=event_id, messages=n)


def run(rt: StageRuntime) -> None:
    with contextlib.ExitStack() as stack:
        with rt.step():
            pub = Publisher(rt, stack)
        stack.callback(pub.close)
        inbox = rt.input
        pub.try_open(clock.now())
        rt.ready()
        while True:
            rt.beat()
            rt.check_stop()
            now = clock.now()
            pub.try_open(now)
            pub.periodic(now)
            msg = inbox.wait(0.05)
            if msg is None:
                continue
            with rt.step():
                t_in = clock.now()
                pub.handle(msg)
                t_out = clock.now()
            rt.done(t_out - t_in, origin(msg), t_out)
