"""Times given on the command line (``--since``/``--until``) -> unix seconds."""

from __future__ import annotations

import math
import re
import time
from datetime import UTC, datetime, timedelta

_RELATIVE = re.compile(r"^-?(\d+(?:\.\d+)?)\s*(s|sec|m|min|h|d|w)$")
_UNIT_S = {"s": 1, "sec": 1, "m": 60, "min": 60, "h": 3600, "d": 86400, "w": 604800}


def parse_time(text: str, now: float | None = None) -> float:
    """Accepts ``now``, ``today``, ``yesterday``, a duration ago (``90s``, ``15m``, ``2h``, ``3d``, ``1w``,
    optionally with a leading ``-``), an ISO 8601 date or date-time (local time unless it has an offset or
    ``Z``), or unix seconds. Raises ValueError naming the accepted forms."""
    now = time.time() if now is None else now
    s = text.strip().lower()
    if s == "now":
        return now
    if s in ("today", "yesterday"):
        midnight = datetime.fromtimestamp(now).replace(hour=0, minute=0, second=0, microsecond=0)
        if s == "yesterday":
            midnight -= timedelta(days=1)
        return midnight.timestamp()
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
