"""The Zenoh side of the client: one session to a posed daemon or to the router of a fleet.

Subscriptions take a robot id or ``"*"`` (every robot) and a callback, called on a Zenoh thread with the
robot id and the decoded message (:mod:`client.types`); a message that cannot be decoded is counted in
``decode_errors`` and handed to ``on_error`` (if given), never to the callback. Queries (``history``,
``state``, ``robots``) block up to their ``timeout`` (seconds). Times in messages: ``time_unix`` (wall clock)
and the robot's capture clock (monotonic seconds, only meaningful on that robot).
"""

from __future__ import annotations

import json
import math
import threading
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass

import zenoh

from posed.client import mount as m
from posed.client import types as t

DEFAULT_ENDPOINT = "tcp/127.0.0.1:7447"
HISTORY_LIMIT = 10000                      # the daemon's largest accepted limit
JSON = "application/json"


PARAMETER_CHARS = (";", "&", "=", "#", "?")   # what a Zenoh selector's parameter value cannot hold


def _error_text(payload: bytes) -> str:
    """An error reply's text: a ``posed.error`` message's ``error`` (what is wrong and how to fix it)."""
    try:
        obj = t.loads(payload)
    except ValueError:
        return payload.decode(errors="replace")
    return str(obj.get("error") or obj)


class PosedClientError(RuntimeError):
    """The client cannot do what was asked (no connection, a query error); the message says what to do."""


class NoAnswerError(PosedClientError):
    """Nobody answered the query in time (no daemon for that robot, or the bus's access control keeps it away)."""


@dataclass(frozen=True)
class Alive:
    """A change in which robots are up: ``alive`` False when the robot's daemon went away."""

    robot: str
    alive: bool


def session_config(mode: str, connect: Iterable[str] = (), listen: Iterable[str] = (),
                   config_file: str | None = None) -> zenoh.Config:
    """A ``zenoh.Config`` for a session in ``mode`` (client, peer, router) connecting to ``connect`` and
    listening on ``listen``, multicast scouting off; ``config_file``: a Zenoh JSON5 file read first (TLS,
    credentials)."""
    zc = zenoh.Config.from_file(config_file) if config_file else zenoh.Config()
    zc.insert_json5("mode", json.dumps(mode))
    zc.insert_json5("connect/endpoints", json.dumps(list(connect)))
    zc.insert_json5("listen/endpoints", json.dumps(list(listen)))
    zc.insert_json5("scouting/multicast/enabled", "false")
    return zc


def _selector(robot: str, tail: str) -> str:
    if not robot or "/" in robot:
        raise ValueError(f"robot {robot!r}: give a robot id or '*' (every robot)")
    return f"posed/{robot}/{tail}"


def _one_robot(robot: str, tail: str) -> str:
    """The key ``posed/ROBOT/tail`` of one robot: ``robot`` a robot id, never ``"*"`` or a key expression."""
    if not isinstance(robot, str) or not robot or any(c in robot for c in "/*$#?") or robot.strip() != robot:
        raise ValueError(f"robot {robot!r}: give one robot id (the daemon's robot_id, e.g. 'kitchen'), "
                         "not '*', a key expression or blank")
    return _selector(robot, tail)


class PosedClient:
    """A posed reader. ``PosedClient.connect(...)`` opens its own session (closed by ``close`` or ``with``);
    ``PosedClient(session)`` uses one the caller owns (one session per process)."""

    def __init__(self, session: zenoh.Session, *, owns_session: bool = False) -> None:
        self.session = session
        self._owns = owns_session
        self._keep: list = []
        self._lock = threading.Lock()
        self._up: set[str] | None = None       # robots with a live token, once robots() was called
        self.decode_errors = 0

    @classmethod
    def connect(cls, endpoints: str | Iterable[str] = DEFAULT_ENDPOINT, *, mode: str = "client",
                wait_s: float = 10.0, config_file: str | None = None, listen: Iterable[str] = ()) -> PosedClient:
        """Open a session to a daemon or router (``mode`` client, or peer with a ``listen`` endpoint to join a
        router as a peer), retrying for ``wait_s``; ``config_file``: a Zenoh JSON5 file (TLS, credentials)."""
        eps = [endpoints] if isinstance(endpoints, str) else list(endpoints)
        deadline = time.monotonic() + wait_s
        while True:
            try:
                return cls(zenoh.open(session_config(mode, eps, listen, config_file)), owns_session=True)
            except zenoh.ZError as exc:
                if time.monotonic() >= deadline:
                    raise PosedClientError(
                        f"cannot connect to {', '.join(eps)}: {str(exc).splitlines()[0]}; is the daemon (posed run) "
                        "or the router running there? posed listens on tcp/127.0.0.1:7447 by default") from None
                time.sleep(0.25)

    def close(self) -> None:
        """Undeclare the subscriptions; close the session if this client opened it."""
        with self._lock:
            keep, self._keep = self._keep, []
        for entity in keep:
            try:
                entity.undeclare()
            except Exception:
                pass
        if self._owns:
            self.session.close()

    def __enter__(self) -> PosedClient:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # ------------------------------------------------------------------ subscriptions
    def _subscribe(self, key: str, decode: Callable[[dict, str], object], callback: Callable,
                   on_error: Callable[[str, Exception], None] | None):
        def on_sample(sample) -> None:
            k = str(sample.key_expr)
            try:
                robot = t.robot_of(k)
                value = decode(t.loads(sample.payload.to_bytes()), robot)
            except (ValueError, KeyError, TypeError) as exc:
                with self._lock:
                    self.decode_errors += 1
                if on_error is not None:
                    on_error(k, exc)
                return
            callback(robot, value)

        sub = self.session.declare_subscriber(key, on_sample)
        with self._lock:
            self._keep.append(sub)
        return sub

    def on_pose(self, robot: str, callback: Callable[[str, object], None], on_error=None):
        """``callback(robot, fitting.FitResult)`` for every pose of ``robot`` (``"*"``: every robot)."""
        return self._subscribe(_selector(robot, "pose"), lambda o, r: t.decode_pose(o), callback, on_error)

    def on_status(self, robot: str, callback: Callable[[str, t.Status], None], on_error=None):
        """``callback(robot, Status)`` about every status_period_s."""
        return self._subscribe(_selector(robot, "status"), t.Status.from_json, callback, on_error)

    def on_event(self, robot: str, callback: Callable[[str, object], None], on_error=None):
        """``callback(robot, falls.FallEvent)`` for every fall-event message. Messages are repeated until
        acknowledged: deduplicate on (event.id, event.state)."""
        return self._subscribe(_selector(robot, "events/fall"), lambda o, r: t.decode_event(o), callback, on_error)

    def on_landmarks(self, robot: str, callback: Callable[[str, t.Landmarks], None], on_error=None):
        """``callback(robot, Landmarks)`` per frame (the daemon publishes them when zenoh.publish_landmarks): the
        landmarks, ``world``, ``people`` (each with its track ``id``), ``depth_m``, ``gravity``, ``floor`` and
        ``raw``, the whole message."""
        return self._subscribe(_selector(robot, "landmarks"), t.Landmarks.from_json, callback, on_error)

    def on_alive(self, callback: Callable[[Alive], None], robot: str = "*"):
        """``callback(Alive)`` when a robot's daemon comes up (also for those already up) or goes away."""
        def on_sample(sample) -> None:
            try:
                robot_id = t.robot_of(str(sample.key_expr))
            except ValueError:
                return
            callback(Alive(robot_id, sample.kind == zenoh.SampleKind.PUT))

        sub = self.session.liveliness().declare_subscriber(_selector(robot, "alive"), on_sample, history=True)
        with self._lock:
            self._keep.append(sub)
        return sub

    # ------------------------------------------------------------------ queries and acknowledgements
    def robots(self, timeout: float = 2.0) -> list[str]:
        """The robots whose daemon is up now (their liveliness token posed/ROBOT/alive), sorted.

        The first call starts following the tokens (a liveliness subscriber, kept) and asks for them (liveliness
        queries, again while none came, for up to ``timeout``: with none up it takes that long); later calls
        answer from what the subscriber saw. (With zenoh 1.10 a liveliness query through a router now and then
        completes at once without a reply while tokens are there, so one query is not a reliable answer.)"""
        with self._lock:
            first = self._up is None
            if first:
                self._up = set()
        if first:
            def on_token(sample) -> None:
                try:
                    robot = t.robot_of(str(sample.key_expr))
                except ValueError:
                    return
                with self._lock:
                    (self._up.add if sample.kind == zenoh.SampleKind.PUT else self._up.discard)(robot)

            sub = self.session.liveliness().declare_subscriber("posed/*/alive", on_token, history=True)
            with self._lock:
                self._keep.append(sub)
            deadline = time.monotonic() + timeout
            while True:             # asked again while nothing came, up to timeout (none up: it takes that long)
                asked = {t.robot_of(str(r.ok.key_expr)) for r in self.session.liveliness().get(
                    "posed/*/alive", timeout=max(0.1, deadline - time.monotonic())) if r.ok is not None}
                with self._lock:
                    self._up |= asked
                    if self._up or time.monotonic() >= deadline:
                        break
                time.sleep(0.1)
        with self._lock:
            return sorted(self._up)

    def _get(self, selector: str, timeout: float) -> list:
        replies = self.session.get(selector, target=zenoh.QueryTarget.ALL,
                                   consolidation=zenoh.ConsolidationMode.NONE, timeout=timeout)
        out, errors = [], []
        for reply in replies:
            if reply.ok is not None:
                out.append((str(reply.ok.key_expr), t.loads(reply.ok.payload.to_bytes())))
            else:
                errors.append(reply.err.payload.to_string())
        if errors and not out:
            raise PosedClientError(f"{selector}: {'; '.join(errors)}")
        return out

    def history(self, robot: str = "*", since: str | float | None = None, until: str | float | None = None,
                limit: int = 100, timeout: float = 5.0, event_id: str | None = None) -> list[t.HistoryEntry]:
        """Stored fall-event messages of ``robot`` (``"*"``: every robot that answers), oldest first by
        ``time_unix``; ``since``/``until``: unix seconds, ISO 8601, ``2h``, ``7d``, ``today``; ``limit`` per robot;
        ``event_id``: that event's messages only, however old (a posed older than this answers such a query with
        an error: :class:`PosedClientError`)."""
        params = [f"limit={int(limit)}"]
        params += [f"{k}={v}" for k, v in (("since", since), ("until", until)) if v is not None]
        tail = "events/history/**"
        if event_id is not None:
            if not isinstance(event_id, str) or not event_id or any(c in event_id for c in "/*$#?; "):
                raise ValueError(f"event_id {event_id!r}: give one event's id (its `id` field)")
            tail = f"events/history/{event_id}/**"
        rows = self._get(_selector(robot, tail) + "?" + ";".join(params), timeout)
        entries = [t.HistoryEntry.from_json(obj) for _, obj in rows]
        return sorted(entries, key=lambda e: (t.time_unix(e.event) or 0.0, e.event.t_detect))

    def state(self, robot: str, timeout: float = 5.0) -> t.State:
        """The robot's latest pose and status (its state queryable)."""
        rows = self._get(_selector(robot, "state"), timeout)
        if not rows:
            raise PosedClientError(f"no answer from robot {robot!r} within {timeout} s; `robots()` lists those up")
        key, obj = rows[0]
        return t.State.from_json(obj, t.robot_of(key))

    def ack(self, robot: str, event_id: str, state: str | None = None, *, by: str | None = None,
            confirm_s: float = 0.0) -> bool:
        """Acknowledge a fall event (every message so far, or only ``state``'s): the daemon stops republishing
        it. With ``confirm_s`` > 0 the robot's history is read until it shows the acknowledgement (the ack is
        put again meanwhile: a put made before the route to the daemon exists can be lost); returns whether it
        was confirmed (always True without ``confirm_s``)."""
        if robot == "*" or not event_id:
            raise ValueError("ack needs one robot id and an event id")
        msg = {"format": "posed.ack", "version": 1, "id": event_id, "time_unix": round(time.time(), 4)}
        if state is not None:
            msg["state"] = state
        if by:
            msg["by"] = by
        key = _selector(robot, "events/ack")
        deadline = time.monotonic() + confirm_s
        while True:
            self.session.put(key, json.dumps(msg), encoding=JSON,
                             congestion_control=zenoh.CongestionControl.BLOCK)
            if confirm_s <= 0:
                return True
            time.sleep(0.2)
            mine = [e for e in self._event_history(robot, event_id)
                    if e.event.id == event_id and (state is None or e.event.state == state)]
            if mine and all(e.acked_at is not None for e in mine):
                return True
            if time.monotonic() >= deadline:
                return False
            time.sleep(0.3)

    def _event_history(self, robot: str, event_id: str) -> list[t.HistoryEntry]:
        """One event's stored messages (``history(event_id=...)``); from a posed older than that query, the newest
        HISTORY_LIMIT messages instead; [] when the robot does not answer."""
        try:
            return self.history(robot, limit=HISTORY_LIMIT, timeout=2.0, event_id=event_id)
        except PosedClientError:
            pass
        try:
            return self.history(robot, limit=HISTORY_LIMIT, timeout=2.0)
        except PosedClientError:
            return []

    # ------------------------------------------------------------------ a pause for privacy
    def pause(self, for_s: float, by: str | None = None, *, robot: str | None = None,
              timeout: float = 5.0) -> t.PrivacyState:
        """Ask ``robot``'s daemon to stop watching for ``for_s`` seconds (its ``posed/ROBOT/privacy/pause``; None:
        the one robot whose daemon is up), said to be asked by ``by`` (free text, at most 64 printable
        characters). A pause replaces the running one (its start is kept); one longer than the robot's
        ``privacy.max_pause_s`` is cut to it (``clamped``); 0 resumes now. Returns the robot's answer; raises
        :class:`PosedClientError` with the daemon's reason and fix when it refuses (pausing not allowed, a fall
        not acknowledged) or does not answer within ``timeout`` seconds, ``ValueError`` on a bad argument."""
        if isinstance(for_s, bool) or not isinstance(for_s, (int, float)) or not math.isfinite(for_s) or for_s < 0:
            raise ValueError(f"for_s={for_s!r}: give how long to pause in seconds (e.g. 900), or 0 to resume")
        return self._privacy(f"for={float(for_s)!r}", by, robot, timeout)

    def resume(self, by: str | None = None, *, robot: str | None = None, timeout: float = 5.0) -> t.PrivacyState:
        """End ``robot``'s pause for privacy now (always allowed; nothing happens when none runs): the robot's
        answer, ``paused`` False. ``by``, ``robot`` and ``timeout`` as for :meth:`pause`."""
        return self._privacy("for=0", by, robot, timeout)

    def _privacy(self, params: str, by: str | None, robot: str | None, timeout: float) -> t.PrivacyState:
        if by is not None:
            if not isinstance(by, str) or any(c in by for c in PARAMETER_CHARS) or not by.isprintable():
                raise ValueError(f"by={by!r}: printable text without {' '.join(PARAMETER_CHARS)} (Zenoh selector "
                                 "parameters cannot carry them)")
            if by.strip():
                params += f";by={by.strip()}"
        if robot is None:
            up = self.robots(timeout=min(timeout, 2.0))
            if not up:
                raise NoAnswerError("no posed daemon is up on this bus: is it running (posed run), and is this "
                                       "the right endpoint? Or name the robot with robot=")
            if len(up) > 1:
                raise PosedClientError(f"{len(up)} robots are up ({', '.join(up)}): say which with robot=")
            robot = up[0]
        key = _one_robot(robot, "privacy/pause")
        replies = self.session.get(f"{key}?{params}", consolidation=zenoh.ConsolidationMode.NONE, timeout=timeout)
        errors = []
        for reply in replies:
            if reply.ok is not None:
                return t.PrivacyState.from_json(t.loads(reply.ok.payload.to_bytes()), robot)
            errors.append(_error_text(reply.err.payload.to_bytes()))
        if errors:
            raise PosedClientError(f"robot {robot}: {'; '.join(errors)}")
        raise NoAnswerError(f"no answer from robot {robot!r} on {key} within {timeout} s: is its daemon running "
                               "(posed run), and may this program query it (the bus's access control)?")

    def set_camera_mount(self, robot: str, *, down=None, tilt_deg: float | None = None,
                         roll_deg: float | None = None, height_m: float | None = None, valid_s: float = 1.0,
                         time_unix: float | None = None, source: str | None = None) -> dict:
        """Tell ``robot``'s daemon where its camera is now (``posed/ROBOT/camera/mount``, ``posed.camera_mount``;
        the daemon uses it with ``falls.camera_mount_from_bus: true``): ``down`` (gravity in the camera's axes:
        x image right, y image down, z forward) or ``tilt_deg`` and ``roll_deg`` (both; falls.camera_tilt_deg's
        and camera_roll_deg's convention), ``height_m`` (the optical centre above the floor, 0.05..5),
        ``valid_s`` (how long it holds, 0.05..3600), ``time_unix`` (when it was true; None: when received),
        ``source`` (free text). Put it at the camera's rate, or at least every ``valid_s``/2 while the camera
        moves. Raises ``ValueError`` naming a bad argument and what it may be; returns the message put."""
        key = _one_robot(robot, m.KEY)
        msg = m.camera_mount_message(down=down, tilt_deg=tilt_deg, roll_deg=roll_deg, height_m=height_m,
                                     valid_s=valid_s, time_unix=time_unix, source=source)
        self.session.put(key, json.dumps(msg, allow_nan=False), encoding=JSON,
                         congestion_control=zenoh.CongestionControl.DROP)
        return msg
