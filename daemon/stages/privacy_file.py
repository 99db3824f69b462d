"""The pause for privacy as it is kept in the state directory: ``privacy.json`` (docs/daemon.md, "Pausing for
privacy"), so that a daemon (or a capture stage) started again during a pause stays paused until it ends.

The file holds the running pause (or none) and the last one that ended::

    {"format": "posed.privacy_file", "version": 1,
     "pause": {"since_unix": 1765.., "until_unix": 1765.., "by": "voice"} | null,
     "last": {"since_unix", "ended_unix", "by", "ended": "time" | "resumed" | "stopped", "resumed_by"} | null}

It is written atomically (a temporary file in the same folder, fsync'd, then renamed over it; mode 0600) by
the publisher's :class:`daemon.stages.privacy_keeper.PrivacyKeeper`, and read by it at start and by the
capture stage at its start (:func:`paused_now`). Times are unix seconds (the wall clock: a pause ends at a
time of day, also across a reboot).
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass
from pathlib import Path

from posed.daemon.history.paused import ENDED
from posed.daemon.outbox.private import write_private

PRIVACY_FILE = "privacy.json"
FILE_FORMAT = "posed.privacy_file"


class PrivacyFileError(ValueError):
    """``privacy.json`` cannot be read or is not one (the message says what is wrong)."""


@dataclass(frozen=True)
class Pause:
    """A pause: from ``since_unix`` to ``until_unix`` (unix seconds), asked by ``by`` (None: not said)."""

    since_unix: float
    until_unix: float
    by: str | None

    def remaining_s(self, now_unix: float) -> float:
        """Seconds left at ``now_unix`` (0 once it ended)."""
        return max(0.0, self.until_unix - now_unix)


@dataclass(frozen=True)
class EndedPause:
    """The last pause that ended: when (``ended_unix``, unix seconds) and how (``ended``: time, resumed or
    stopped, the daemon stopped during it), and who resumed it (``resumed_by``)."""

    since_unix: float
    ended_unix: float
    by: str | None
    ended: str
    resumed_by: str | None = None


def privacy_path(state_dir: Path) -> Path:
    return Path(state_dir) / PRIVACY_FILE


def write_privacy_file(path: Path, pause: Pause | None, last: EndedPause | None) -> None:
    """Write the file atomically (mode 0600); raises OSError (a read-only or full state dir)."""
    path = Path(path)
    text = json.dumps({"format": FILE_FORMAT, "version": 1,
                       "pause": asdict(pause) if pause is not None else None,
                       "last": asdict(last) if last is not None else None}, sort_keys=True)
    write_private(path, text)


def _time(obj: dict, key: str) -> float:
    v = obj.get(key)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise PrivacyFileError(f"{key} is {v!r}, not unix seconds")
    return float(v)


def _text(obj: dict, key: str) -> str | None:
    v = obj.get(key)
    if v is not None and not isinstance(v, str):
        raise PrivacyFileError(f"{key} is {v!r}, not text")
    return v


def read_privacy_file(path: Path) -> tuple[Pause | None, EndedPause | None]:
    """The pause and the last ended one in the file ((None, None) when there is no file); raises
    :class:`PrivacyFileError` when it cannot be read or is not one."""
    path = Path(path)
    try:
        raw = path.read_text()
    except FileNotFoundError:
        return None, None
    except (OSError, UnicodeDecodeError) as exc:
        raise PrivacyFileError(f"cannot read it: {exc}") from None
    try:
        obj = json.loads(raw)
    except ValueError as exc:
        raise PrivacyFileError(f"not JSON: {exc}") from None
    if not isinstance(obj, dict) or obj.get("format") != FILE_FORMAT:
        raise PrivacyFileError(f"not a {FILE_FORMAT} object")
    pause = last = None
    p = obj.get("pause")
    if p is not None:
        if not isinstance(p, dict):
            raise PrivacyFileError("pause is not an object")
        pause = Pause(_time(p, "since_unix"), _time(p, "until_unix"), _text(p, "by"))
    e = obj.get("last")
    if e is not None:
        if not isinstance(e, dict) or e.get("ended") not in ENDED:
            raise PrivacyFileError(f"last is not an ended pause (ended: one of {', '.join(ENDED)})")
        last = EndedPause(_time(e, "since_unix"), _time(e, "ended_unix"), _text(e, "by"), e["ended"],
                          _text(e, "resumed_by"))
    return pause, last


def paused_now(state_dir: Path, now_unix: float) -> Pause | None:
    """The pause in the state dir's file that still runs at ``now_unix``; None when there is none, it ended,
    or the file cannot be read (the publisher's keeper says so in the log)."""
    try:
        pause, _ = read_privacy_file(privacy_path(state_dir))
    except PrivacyFileError:
        return None
    return pause if pause is not None and pause.until_unix > now_unix else None
