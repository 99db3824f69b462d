"""Times given on the command line (``--since``/``--until``) -> unix seconds, and the times the command line
prints back to people: in one zone, the robot's (the zone ``posed report`` and ``posed plot history`` use),
each with its UTC offset, so that a time in the hour the clocks go back reads unambiguously.

Standard library only: ``posed events`` imports it and must stay fast (no numpy)."""

from __future__ import annotations

import math
import os
import re
import time
from datetime import UTC, datetime, timedelta, tzinfo
from pathlib import Path
from zoneinfo import ZoneInfo

_RELATIVE = re.compile(r"^-?(\d+(?:\.\d+)?)\s*(s|sec|m|min|h|d|w)$")
_UNIT_S = {"s": 1, "sec": 1, "m": 60, "min": 60, "h": 3600, "d": 86400, "w": 604800}
# a time stamped later than now by more than this was stamped by a clock that was wrong then or is wrong now
# (NTP slews small errors and steps only large ones; daemon.stages.restored_falls takes it, viz.series has its twin)
FUTURE_SLACK_S = 2.0


def local_zone(name: str | None = None) -> tzinfo:
    """The time zone ``name`` (IANA, e.g. ``Europe/Berlin``), else this machine's (the robot's) local zone:
    ``$TZ``, else the zone /etc/localtime points at (so summer time is right on every date), else the current
    UTC offset as a fixed zone. Raises ValueError naming an unknown ``name`` and what to give instead.
    The one rule of every time shown to people: the commands pass its zone to ``viz``'s plots and report."""
    if name:
        try:
            return ZoneInfo(name)
        except (KeyError, ValueError) as exc:     # zoneinfo.ZoneInfoNotFoundError is a KeyError
            raise ValueError(f"unknown time zone {name!r} ({exc}); use an IANA name such as Europe/Berlin") from None
    env = os.environ.get("TZ", "").lstrip(":")
    if env:
        try:
            return ZoneInfo(env)
        except (KeyError, ValueError):
            pass
    link = Path("/etc/localtime")
    if link.is_symlink():
        target = str(link.resolve())
        if "zoneinfo/" in target:
            try:
                return ZoneInfo(target.split("zoneinfo/", 1)[1])
            except (KeyError, ValueError):
                pass
    return datetime.now().astimezone().tzinfo


def zone_name(tz: tzinfo, at: float | None = None) -> str:
    """``Europe/London`` (the IANA key), else the zone's abbreviation at ``at``, else ``UTC``."""
    key = getattr(tz, "key", None)
    if key:
        return key
    return datetime.fromtimestamp(time.time() if at is None else at, tz).tzname() or "UTC"


def clock_text(unix: float, tz: tzinfo) -> str:
    """``2026-10-25T01:30:05+01:00``: ISO 8601, the date and time in ``tz`` with its UTC offset (so the two 01:30
    of the night the clocks go back read apart), one word (a listing's columns stay split by blanks)."""
    return datetime.fromtimestamp(unix, tz).isoformat(timespec="seconds")


def until_text(unix: float, tz: tzinfo, now: float | None = None, zone: bool = True) -> str:
    """When something ends, as a person reads it: ``15:42 CET`` today in ``tz``, ``2026-12-08 00:19 JST`` on
    another day (a pause running past midnight); without the zone's name when ``zone`` is false."""
    at = datetime.fromtimestamp(unix, tz)
    today = datetime.fromtimestamp(time.time() if now is None else now, tz).date()
    text = at.strftime("%H:%M" if at.date() == today else "%Y-%m-%d %H:%M")
    return f"{text} {at.tzname() or ''}".strip() if zone else text


def future_note(unix: float, now: float | None = None) -> str:
    """What to say of a time stamped later than ``now`` (empty when it is not): a clock that was wrong when it
    was stamped (set right later, e.g. by NTP after boot on a robot without an RTC battery) or that is wrong
    now. Such a time is never taken for the truth, nor a duration computed from it."""
    now = time.time() if now is None else now
    ahead = unix - now
    if ahead <= FUTURE_SLACK_S:
        return ""
    return (f"stamped {duration_text(ahead)} later than now by this machine's clock: the robot's clock was wrong "
            "when it was recorded (set right since, e.g. by NTP at boot) or is wrong now (timedatectl)")


def duration_text(seconds: float) -> str:
    """``3 d 4 h``, ``2 h 05 min``, ``12 min``, ``40 s`` (of a positive number of seconds)."""
    s = int(round(seconds))
    if s >= 86400:
        return f"{s // 86400} d {s % 86400 // 3600} h"
    if s >= 3600:
        return f"{s // 3600} h {s % 3600 // 60:02d} min"
    return f"{s // 60} min" if s >= 60 else f"{s} s"


def parse_time(text: str, now: float | None = None, tz: tzinfo | None = None) -> float:
    """Accepts ``now``, ``today``, ``yesterday``, a duration ago (``90s``, ``15m``, ``2h``, ``3d``, ``1w``,
    optionally with a leading ``-``), an ISO 8601 date or date-time (in ``tz``, default this machine's local
    time, unless it has an offset or ``Z``; a time in the hour the clocks go back is its first occurrence), or
    unix seconds. Raises ValueError naming the accepted forms."""
    now = time.time() if now is None else now
    s = text.strip().lower()
    if s == "now":
        return now
    if s in ("today", "yesterday"):
        day = datetime.fromtimestamp(now, tz).date()
        if s == "yesterday":
            day -= timedelta(days=1)
        return datetime(day.year, day.month, day.day, tzinfo=tz).timestamp()
    m = _RELATIVE.match(s)
    if m:
        return _finite(now - float(m.group(1)) * _UNIT_S[m.group(2)], text)
    if re.fullmatch(r"\d{9,}(\.\d+)?", s):
        return _finite(float(s), text)
    try:
        dt = datetime.fromisoformat(text.strip().replace("Z", "+00:00").replace("z", "+00:00"))
    except ValueError:
        raise ValueError(
            f"{text!r} is not a time; use now, today, yesterday, a duration ago (30m, 2h, 7d), "
            "an ISO date or date-time (2024-05-01, 2024-05-01T14:30, 2024-05-01T12:30Z) or unix seconds"
        ) from None
    if dt.tzinfo is None and tz is not None:
        dt = dt.replace(tzinfo=tz)
    try:
        return dt.timestamp()
    except (OverflowError, OSError, ValueError):    # e.g. 0001-01-01 in a time zone east of UTC
        raise ValueError(f"{text!r} is outside the range of times this machine can represent") from None


def _finite(t: float, text: str) -> float:
    if not math.isfinite(t):
        raise ValueError(f"{text[:40]!r} is too large to be a time")
    return t


def iso(unix: float) -> str:
    return datetime.fromtimestamp(unix, UTC).isoformat(timespec="seconds")
