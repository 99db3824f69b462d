"""The joint-angle history and the event journal as ``posed plot history`` and ``posed report`` take them
(``viz.series``); the drawing itself is ``viz.plots`` (matplotlib). Command-line only: the service stores
the history (``daemon.history``) and never draws it.

Clock: the history's ``wall`` column is the robot's unix time when the frame was stored (the publisher stage,
a few milliseconds after capture); a journal message's ``wall`` is when it was journalled and ``acked_at``
when a receiver acknowledged it, on the same clock.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

from posed.client.types import restored, without_frames_s
from posed.viz.series import AngleSeries, EventMark


def angle_series(rows: Sequence[tuple], columns: Sequence[str]) -> AngleSeries:
    """History rows ``(wall, t, seq, level, *columns)`` (``AngleHistory.rows``) as a clock-time series."""
    wall = [r[0] for r in rows]
    return AngleSeries.from_rows(wall, {name: [r[4 + i] for r in rows] for i, name in enumerate(columns)})


def event_marks(stored: Iterable) -> list[EventMark]:
    """Journal messages (``StoredEvent``) as marks on the clock, each with whose fall it is when known."""
    return [EventMark(s.event.id, s.event.state, s.wall, s.acked_at, whose(s.event.extra),
                      getattr(s, "acked_by", None), *caveats(s.event)) for s in stored]


def caveats(event) -> tuple[float | None, float | None]:
    """A message's ``restored`` (when posed took the open fall back after a restart, unix s) and
    ``without_frames_s`` (an alarm raised with no camera frame for that long); None when absent or malformed
    (the client's readers of the two fields)."""
    taken_back = restored(event)
    return (taken_back.at_unix if taken_back is not None else None, without_frames_s(event))


def whose(extra: dict) -> str | None:
    """Whose fall a message is, in words: the household member's name, "a visitor", "person N" (several
    people, no household), None (one person)."""
    if extra.get("member"):
        return str(extra["member"])
    if (extra.get("household") or {}).get("visitor"):
        return "a visitor"
    return None if extra.get("person") is None else f"person {extra['person']}"
