"""What a query on ``posed/ROBOT/privacy/pause`` asks (docs/daemon.md, "Pausing for privacy"), read from its
selector parameters:

* ``for`` (required): how long, in seconds (``900``, ``90.5``) or with units (``30s``, ``15m``, ``1h``,
  ``1h30m``, ``1h30m15s``); ``0`` or ``resume``: resume now;
* ``by`` (optional): who asks, free text of at most :data:`MAX_BY_CHARS` printable characters; blank or absent:
  nobody named (None).

Zenoh separates parameters with ``;``; a URL habit (``for=15m&by=voice``) reaches the daemon as one value and is
read the same way. Every rejection is a :class:`BadPause` naming the parameter, what was wrong and how to ask.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Callable
from dataclasses import dataclass

from posed.daemon.bus.inbound import query_values, text_field

MAX_BY_CHARS = 64
USAGE = ("for: how long, seconds (900, 90.5) or 30s, 15m, 1h, 1h30m; 0 or resume resumes now; by: who asks "
         f"(optional, at most {MAX_BY_CHARS} printable characters), e.g. posed/ROBOT/privacy/pause?for=15m;by=voice")
_UNITS = re.compile(r"(?:(\d+(?:\.\d+)?)h)?(?:(\d+(?:\.\d+)?)m)?(?:(\d+(?:\.\d+)?)s)?")


class BadPause(ValueError):
    """A pause query that cannot be read: the message names the parameter and how to give it."""


class PauseRefused(Exception):
    """A pause that may not be made now: ``error`` what stands in the way, ``fix`` what to do about it."""

    def __init__(self, error: str, fix: str) -> None:
        super().__init__(f"{error}; {fix}")
        self.error = error
        self.fix = fix


@dataclass(frozen=True)
class PauseRequest:
    """One pause query: ``for_s`` seconds (0: resume now) asked by ``by`` (None: not said)."""

    for_s: float
    by: str | None

    @property
    def resume(self) -> bool:
        return self.for_s == 0.0


def parse_duration(text: str) -> float:
    """Seconds in ``900``, ``90.5``, ``30s``, ``15m``, ``1h``, ``1h30m`` (``resume``: 0); raises :class:`BadPause`."""
    s = text.strip().lower()
    if not s:
        raise BadPause(f"for is empty; {USAGE}")
    if s == "resume":
        return 0.0
    try:
        seconds = float(s)
    except ValueError:
        m = _UNITS.fullmatch(s)
        if m is None or not any(m.groups()):
            raise BadPause(f"for={text[:40]!r} is not a duration; {USAGE}") from None
        h, mins, secs = (float(g) if g else 0.0 for g in m.groups())
        seconds = h * 3600.0 + mins * 60.0 + secs
    if not math.isfinite(seconds):
        raise BadPause(f"for={text[:40]!r} is not a finite duration; {USAGE}")
    if seconds < 0:
        raise BadPause(f"for={text[:40]!r} is negative; give how long to pause (e.g. 15m), or 0 to resume")
    return seconds


def parse_by(text: str | None) -> str | None:
    """Who asks: None when absent or blank; raises :class:`BadPause` beyond MAX_BY_CHARS or not printable
    (:func:`daemon.bus.inbound.text_field`, as an acknowledgement's ``by``)."""
    return None if text is None else text_field(text, "by", MAX_BY_CHARS, BadPause)


def parse_pause(params) -> PauseRequest:
    """The :class:`PauseRequest` of a query's parameters; raises :class:`BadPause` naming what is wrong."""
    found = query_values(params, ("for", "by"))
    if "for" not in found:
        raise BadPause(f"for is missing: say how long to pause, or 0 to resume; {USAGE}")
    return PauseRequest(parse_duration(found["for"]), parse_by(found.get("by")))


def answer_pause(query, key: str, ask: Callable[[PauseRequest], dict], log, throttle) -> None:
    """Reply to one query on ``posed/ROBOT/privacy/pause`` (a Zenoh thread): ``ask(request)`` makes the change and
    gives the ``posed.privacy`` message; a query that cannot be read, or a refused pause, gets a ``posed.error``
    reply whose ``error`` says what is wrong and how to fix it (``fix``: the fix alone). Never raises."""
    from posed.daemon.bus import payloads

    try:
        try:
            request = parse_pause(query.parameters)
        except BadPause as exc:
            suppressed = throttle.allow("bad_pause_query")
            if suppressed is not None:
                log.warning("bad_pause_query", error=str(exc)[:200], suppressed=suppressed)
            out = payloads.error_message(str(exc), USAGE)
            out["fix"] = USAGE
            query.reply_err(json.dumps(out), encoding=payloads.JSON_ENCODING)
            return
        try:
            message = ask(request)
        except PauseRefused as exc:
            out = payloads.error_message(str(exc))
            out["fix"] = exc.fix
            query.reply_err(json.dumps(out), encoding=payloads.JSON_ENCODING)
            return
        query.reply(key, payloads.dumps(message), encoding=payloads.JSON_ENCODING)
    except Exception as exc:        # never into Zenoh's thread
        log.warning("pause_query_failed", error=repr(exc))
