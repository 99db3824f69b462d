"""What the topics carry (interfaces.md section 4, docs/formats.md): JSON text without NaN, and every message
object stamped with its contract fields — ``format`` and ``version`` (:mod:`client.contract`, whose JSON Schemas
describe each message), ``robot``, and ``time_unix`` (unix seconds) next to the robot's capture-clock time.

Capture-clock times (``t``, ``t_onset``, ``t_impact``, ``t_detect``) are seconds on the robot's monotonic clock:
only differences on one robot mean anything. Their unix equivalents are computed when the message is made
(``clock.wall_from_monotonic``) and travel with it, so a fall event republished after a restart still says when
it happened. Fields are only added here, never renamed (``setdefault`` keeps what the object already has).
"""

from __future__ import annotations

import json
import math
from dataclasses import replace
from datetime import datetime

from posed.client.contract import VERSION
from posed.daemon import clock
from posed.daemon.messages import FitMsg, origin, timing_ms
from posed.falls import FallEvent

JSON_ENCODING = "application/json"   # every publication and every query reply (zenoh.Encoding.APPLICATION_JSON)


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


def _unix(t: float | None) -> float | None:
    return None if t is None else round(clock.wall_from_monotonic(t), 4)


def stamp(obj: dict, fmt: str, robot: str | None = None, time_unix: float | None = None) -> dict:
    """``obj`` with ``format``, ``version`` and (when given) ``robot`` and ``time_unix`` set where absent."""
    obj.setdefault("format", fmt)
    obj.setdefault("version", VERSION)
    if robot is not None:
        obj.setdefault("robot", robot)
    if time_unix is not None:
        obj.setdefault("time_unix", time_unix)
    return obj


def pose_message(msg: FitMsg, now: float, robot: str = "") -> dict:
    """The pose topic's JSON object for one FitMsg: the fit result (interfaces.md section 2) plus
    ``time_unix`` (the capture time in unix seconds), ``image_size`` and ``timing_ms`` (per-stage work and
    latency up to ``now``, seconds on the monotonic clock), ``format`` posed.pose, ``version``, ``robot``."""
    out = msg.result.to_json()
    stamp(out, "posed.pose", robot, _unix(msg.t_capture))
    out.setdefault("image_size", list(msg.image_size))
    out.setdefault("timing_ms", timing_ms(msg.stamps, origin(msg), now))
    return out


def landmarks_message(msg: FitMsg, robot: str = "") -> dict:
    """The landmarks topic's JSON object: the frame object of interfaces.md section 1 plus ``image_size``,
    ``time_unix`` (capture time), ``format`` posed.landmarks_frame, ``version`` and ``robot``."""
    out = msg.landmarks.to_json()
    out["image_size"] = list(msg.image_size)
    return stamp(out, "posed.landmarks_frame", robot, _unix(msg.t_capture))


def status_message(status: dict, robot: str, now: float) -> dict:
    """The status object plus ``format`` posed.status, ``version``, ``robot``, ``time_unix`` and ``t`` (when it
    was composed, unix seconds and the monotonic clock). The supervisor names the software's version
    ``posed_version``: every message's ``version`` is its format's."""
    out = dict(status)
    out.setdefault("t", round(now, 4))
    return stamp(out, "posed.status", robot, _unix(now))


def stamp_event(event: FallEvent) -> FallEvent:
    """A new event message with its times as unix seconds (``time_unix`` = t_detect, ``t_onset_unix``,
    ``t_impact_unix``), ``format`` and ``version``: done before it is journalled, so the journal, every
    republication and the history carry them."""
    extra = {"format": "posed.fall_event", "version": VERSION, "time_unix": _unix(event.t_detect),
             "t_onset_unix": _unix(event.t_onset), "t_impact_unix": _unix(event.t_impact), **event.extra}
    return replace(event, extra=extra)


def event_message(obj: dict) -> dict:
    """A journalled event message as published or answered: ``format`` and ``version`` set where absent (a
    message journalled by an older posed), and ``time_unix`` from ``wall_time`` (when it was journalled, within
    milliseconds of the detection) when the message has none."""
    out = dict(obj)
    if "time_unix" not in out and out.get("wall_time"):
        try:
            out["time_unix"] = round(datetime.fromisoformat(out["wall_time"]).timestamp(), 4)
        except ValueError:
            pass
    return stamp(out, "posed.fall_event")


def state_message(snapshot: dict, robot: str, now_unix: float) -> dict:
    """The reply to a state query: ``{"pose": latest pose, "status": latest status}`` plus the contract
    fields (``time_unix``: when answered)."""
    return stamp(dict(snapshot), "posed.state", robot, round(now_unix, 4))


def history_message(events: list[dict], robot: str, now_unix: float) -> dict:
    """The one reply to a query on the bare history key."""
    return stamp({"events": [event_message(e) for e in events], "count": len(events)}, "posed.event_history",
                 robot, round(now_unix, 4))


def error_message(error: str, usage: str | None = None) -> dict:
    """An error reply to a query."""
    out = {"error": error}
    if usage:
        out["usage"] = usage
    return stamp(out, "posed.error")
