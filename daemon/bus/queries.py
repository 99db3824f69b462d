"""What the bus answers and accepts on Zenoh's own threads: the ``state`` and ``events/history`` queries and
the acknowledgements put on ``events/ack`` (interfaces.md section 4).

Each handler takes what it reads as an argument (the latest pose and status, a journal lookup), so it can be
tested with a stand-in query and no session.
"""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Callable, Sequence

import zenoh

from posed.daemon.bus import payloads
from posed.daemon.bus.inbound import query_values
from posed.daemon.bus.payloads import JSON_ENCODING, dumps

HISTORY_DEFAULT_LIMIT = 100
HISTORY_MAX_LIMIT = 10000
HISTORY_USAGE = "since, until: unix seconds or ISO 8601 (also 2h, 7d, today); limit: integer"

# (since, until, limit) -> the stored messages, oldest first; each has .event (.id, .state) and .to_json()
HistoryLookup = Callable[[float | None, float | None, int, str | None], Sequence]


class LatestState:
    """The latest pose and status objects, written by the stage's loop and read by the state queryable."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._pose: dict | None = None
        self._status: dict | None = None

    def set_pose(self, pose: dict) -> None:
        with self._lock:
            self._pose = pose

    def set_status(self, status: dict) -> None:
        with self._lock:
            self._status = status

    def snapshot(self) -> dict:
        """``{"pose": ..., "status": ...}`` (None until the first of each)."""
        with self._lock:
            return {"pose": self._pose, "status": self._status}


def answer_state(query, key: str, latest: LatestState, log) -> None:
    """Reply to a ``state`` query with the latest pose and status (a posed.state message, JSON)."""
    try:
        robot = key.split("/")[1] if key.count("/") >= 2 else ""
        query.reply(key, dumps(payloads.state_message(latest.snapshot(), robot, time.time())), encoding=JSON_ENCODING)
    except Exception as exc:
        log.warning("state_query_failed", error=repr(exc))


def parse_history_parameters(params) -> tuple[float | None, float | None, int]:
    """since/until (unix seconds, ISO 8601 or relative forms such as 2h) and limit from a query's parameters;
    raises ValueError naming the bad one."""
    from posed.daemon.timeparse import parse_time

    found = query_values(params, ("since", "until", "limit"))      # since=2h&limit=50 read as two

    def get(key):
        v = found.get(key)
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


def event_of_query(key: str, base: str) -> str | None:
    """The event id a history query names (``<base>/<id>/**`` or ``<base>/<id>/<state>``: a first chunk after
    ``base`` with no wildcard), else None (every event)."""
    rest = key[len(base) + 1:] if key.startswith(base + "/") else ""
    chunk = rest.split("/", 1)[0]
    return chunk if chunk and not any(c in chunk for c in "*$") else None


def answer_history(query, base: str, lookup: HistoryLookup, log) -> None:
    """One reply per stored message, each on its own key ``<base>/<id>/<state>`` (so that consolidation cannot
    merge them), only those within the query's key expression (``<base>/<id>/**``: one event's messages, looked up
    by its id however old; ``<base>/*/alarm``: the alarms); a query on the bare key ``base`` (which cannot accept
    other keys) gets one reply holding the list. A bad parameter gets an error reply naming it."""
    try:
        since, until, limit = parse_history_parameters(query.parameters)
    except ValueError as exc:
        query.reply_err(json.dumps(payloads.error_message(str(exc), HISTORY_USAGE)), encoding=JSON_ENCODING)
        return
    try:
        asked = str(query.key_expr)
        stored = lookup(since, until, limit, event_of_query(asked, base))
        if asked == base:
            robot = base.split("/")[1] if base.count("/") >= 2 else ""
            query.reply(base, dumps(payloads.history_message([s.to_json() for s in stored], robot, time.time())),
                        encoding=JSON_ENCODING)
        else:
            within = zenoh.KeyExpr(asked)
            for s in stored:
                key = f"{base}/{s.event.id}/{s.event.state}"
                if within.intersects(zenoh.KeyExpr(key)):     # Zenoh refuses a reply outside the query's keys
                    query.reply(key, dumps(payloads.event_message(s.to_json())), encoding=JSON_ENCODING)
    except Exception as exc:
        log.warning("history_query_failed", error=repr(exc))
        try:
            query.reply_err(json.dumps(payloads.error_message(repr(exc))), encoding=JSON_ENCODING)
        except Exception:
            pass


def parse_ack(payload: str) -> str:
    """The event id in an acknowledgement (:func:`daemon.bus.acks.parse_ack_message`); "" when none."""
    from posed.daemon.bus.acks import BadAck, parse_ack_message

    try:
        return parse_ack_message(payload).id
    except BadAck:
        return ""
