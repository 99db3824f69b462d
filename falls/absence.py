"""Not seen for longer than usual: the person's own routine, learned from the minutes posed watched.

A fall in another room is never seen; the only sign is that the person does not come back into view. From the
per-minute watch counts (the history's ``watched`` table: seconds watched and seconds with a person in view)
this module says when the current absence began, how long posed has watched since, and how long the person
was out of view at most, on each of the last days, from the same time of day (docs/falls.md, "Not seen for
longer than usual").

* A minute SAW the person when its person seconds reach ``SEEN_S`` = 2 s: someone walking through a 3-4 m wide
  view at about 1 m/s is in it for 3-4 s; one or two spurious frames (0.1-0.2 s at 10 fps) are not.
* The absence starts at ``t0`` = the end of the last minute that saw the person (:func:`last_seen`); its
  length is the WATCHED seconds since (:func:`watched_between`): minutes not watched add nothing.
* For each past day ``d`` = 1..``days``, ``t_d`` = the same wall-clock time d days before ``t0`` in the
  robot's time zone (:func:`day_starts`; UTC days without one). The day is the minutes with start in
  [t_d, t_d + DAY_S), before t0; it counts when posed watched at least ``DAY_MIN_WATCHED_S`` (half a day) of it.
* Its ``r_d``: every time the person went out of view within ``WINDOW_S`` (1.5 h) of t_d that day (the end of a
  minute that saw them), and t_d itself, the watched seconds from then (from t_d if then was later) until the
  first minute that saw them again; the largest. Not back within the day: the value runs to the day's end
  (censored; the person was away: it can only make the usual larger, posed quieter). So a bedtime up to 1.5 h
  earlier than ever waits for the usual wake-up, and an outing that began up to 1.5 h either side counts whole.
* The usual (:func:`usual_absence`) is the largest r_d of the counted days; None ("learning") while fewer than
  ``learn_days`` count. The notice is due when the absence's watched seconds exceed usual + a margin.

Limits (docs/falls.md): out of view more than 1.5 h earlier than on any of the past days compares with days the
person was still up, and gives a notice; the usual at any time is at least the time until the person is back
after going out of view 1.5 h later on past days (the price of the window); anyone seen ends an absence; a
person away looks the same as one lying in another room.

Pure: numpy and the standard library; no clock, no I/O. Times are unix seconds, durations seconds.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from datetime import datetime, timedelta, tzinfo
from numbers import Integral, Real

import numpy as np

SEEN_S = 2.0                      # s of a minute with the person in view for it to have SEEN them
DAY_S = 86400.0                   # s in a (UTC) day
DAY_MIN_WATCHED_S = 12 * 3600.0   # s watched in a day's window for the day to count (half the day)
MINUTE_S = 60.0                   # s in a minute (a row's minute is its start, a multiple of this)
WINDOW_S = 1.5 * 3600.0           # s either side of the time of day whose outings count (docs: "Why 1.5 h")


@dataclass(frozen=True, eq=False)   # eq=False: arrays compare element by element, not to one bool
class Minutes:
    """Per-minute watch counts: ``minute`` the starts (unix s, ascending, unique), ``watched_s`` the seconds
    watched in each (normally 0..60), ``person_s`` the seconds with a person in view (0..watched_s). Minutes
    without a row were not watched. The arrays are float64, (n,), read-only copies."""

    minute: np.ndarray
    watched_s: np.ndarray
    person_s: np.ndarray
    _cum: np.ndarray = field(init=False, repr=False)   # (n + 1,): watched seconds before each minute

    def __post_init__(self) -> None:
        arrays = {}
        for name in ("minute", "watched_s", "person_s"):
            a = np.array(getattr(self, name), dtype=np.float64)
            if a.ndim != 1:
                raise ValueError(f"Minutes.{name} must be one-dimensional (one value per minute), "
                                 f"got shape {a.shape}")
            if not np.all(np.isfinite(a)):
                raise ValueError(f"Minutes.{name} must be finite (Minutes.from_rows cleans damaged rows)")
            a.setflags(write=False)
            arrays[name] = a
        n = len(arrays["minute"])
        for name in ("watched_s", "person_s"):
            if len(arrays[name]) != n:
                raise ValueError(f"Minutes.{name} has {len(arrays[name])} values for {n} minutes; "
                                 "one per minute is needed")
            if np.any(arrays[name] < 0):
                raise ValueError(f"Minutes.{name} must be >= 0 s (Minutes.from_rows cleans damaged rows)")
        if not np.all(np.diff(arrays["minute"]) > 0):
            raise ValueError("Minutes.minute must be strictly ascending (unique minute starts); "
                             "Minutes.from_rows sorts and sums duplicates")
        for name, a in arrays.items():
            object.__setattr__(self, name, a)
        cum = np.concatenate(([0.0], np.cumsum(arrays["watched_s"])))
        cum.setflags(write=False)
        object.__setattr__(self, "_cum", cum)

    @classmethod
    def from_rows(cls, rows: Iterable) -> Minutes:
        """From rows ``(minute, watched_s, person_s)`` in any order (the history's ``watched`` rows): minutes
        floored to the minute's start and sorted, rows of the same minute summed; a NaN, infinite or negative
        count (or None) is 0 s; a row without a finite minute, or not three numbers, is dropped. A damaged row
        never raises."""
        rows = list(rows)
        try:
            a = np.array(rows, dtype=np.float64)
        except (TypeError, ValueError):      # ragged, or something that is not a number
            a = None
        if a is None or a.ndim != 2 or a.shape[1] != 3:
            a = np.array([r for r in map(_row, rows) if r is not None], dtype=np.float64).reshape(-1, 3)
        a = a[np.isfinite(a[:, 0])]
        counts = np.where(np.isfinite(a[:, 1:]) & (a[:, 1:] > 0), a[:, 1:], 0.0)
        starts, where = np.unique(np.floor(a[:, 0] / MINUTE_S) * MINUTE_S, return_inverse=True)
        summed = np.zeros((len(starts), 2))
        np.add.at(summed, where.reshape(-1), counts)
        return cls(starts, summed[:, 0], summed[:, 1])

    def __len__(self) -> int:
        return len(self.minute)


def _row(r) -> tuple[float, float, float] | None:
    """A row as three floats (None is NaN, as numpy reads it); None when it is not three numbers."""
    try:
        return tuple(math.nan if x is None else float(x) for x in r) if len(r) == 3 else None
    except (TypeError, ValueError):
        return None


def last_seen(m: Minutes, before: float | None = None, seen_s: float = SEEN_S) -> float | None:
    """The moment the person was last seen (unix s): the end (start + 60 s) of the last minute with start
    before ``before`` (unix s; all minutes when None) whose person seconds reach ``seen_s``; None when none
    did."""
    _check_seen(seen_s)
    stop = len(m) if before is None else int(np.searchsorted(m.minute, _finite("before", before), "left"))
    seen = np.flatnonzero(m.person_s[:stop] >= seen_s)
    return None if len(seen) == 0 else float(m.minute[seen[-1]] + MINUTE_S)


def watched_between(m: Minutes, start: float, end: float) -> float:
    """The seconds watched in the minutes whose start lies in [``start``, ``end``) (unix s); 0 when
    ``end`` <= ``start``. Minutes without a row add nothing."""
    i, j = np.searchsorted(m.minute, [_finite("start", start), _finite("end", end)], "left")
    return float(m._cum[j] - m._cum[i]) if j > i else 0.0


@dataclass(frozen=True)
class Usual:
    """How long the person was out of view at most, from ``t0``'s time of day, on the past days counted.

    ``t0`` (unix s): the absence start it was computed for; ``usual_s`` (s watched): the largest ``per_day``,
    None while learning; ``days``: the past days counted (watched at least half the day); ``learn_days``: the
    days needed before there is a usual; ``per_day`` (s watched): each counted day's r_d, newest first;
    ``censored``: the counted days on which the person, out of view within the window, was not
    seen again within the day (a value runs to the day's end)."""

    t0: float
    usual_s: float | None
    days: int
    learn_days: int
    per_day: tuple[float, ...]
    censored: int

    @property
    def learning(self) -> bool:
        """True while fewer than ``learn_days`` days count (no usual yet)."""
        return self.usual_s is None

    def notice_after_s(self, margin_s: float) -> float | None:
        """The watched seconds of absence after which the notice is due: ``usual_s`` + ``margin_s`` (s, >= 0);
        None while learning."""
        if isinstance(margin_s, bool) or not isinstance(margin_s, Real) or not 0 <= margin_s < math.inf:
            raise ValueError(f"margin_s must be a finite number of seconds >= 0, got {margin_s!r}")
        return None if self.usual_s is None else self.usual_s + float(margin_s)


def usual_absence(m: Minutes, t0: float, days: int = 14, learn_days: int = 7, seen_s: float = SEEN_S,
                  day_min_watched_s: float = DAY_MIN_WATCHED_S, *, tz: tzinfo | None = None,
                  window_s: float = WINDOW_S) -> Usual:
    """The usual absence from ``t0`` (unix s) on the past ``days`` days (module doc). Day d = 1..``days``
    starts at ``t_d``, the wall-clock time of ``t0`` d days before in ``tz`` (None: UTC days, t0 - d * DAY_S),
    and is the minutes with start in [t_d, min(t_d + DAY_S, t0)); it counts when ``day_min_watched_s``
    (s, 0..DAY_S) of it were watched. A minute SAW the person when its person seconds reach ``seen_s``
    (s, 0 < seen_s <= 60). The candidates are t_d and the end of every SAW minute with the end in
    (t_d - ``window_s``, t_d + ``window_s``] (s, 0..DAY_S / 2); each one's value is the watched seconds from
    the earlier of it and t_d to the first SAW minute at or after it, or to the day's end (censored) when none
    is in the day; r_d is the largest value. Only minutes before t0 are used. ``learn_days`` > ``days`` is
    allowed and means always learning."""
    t0 = _finite("t0", t0)
    days = _count("days", days, "the past days looked at")
    learn_days = _count("learn_days", learn_days, "the counted days needed before there is a usual")
    _check_seen(seen_s)
    if isinstance(day_min_watched_s, bool) or not isinstance(day_min_watched_s, Real) \
            or not 0 <= day_min_watched_s <= DAY_S:
        raise ValueError(f"day_min_watched_s must be in [0, {DAY_S:g}] s, got {day_min_watched_s!r}")
    if isinstance(window_s, bool) or not isinstance(window_s, Real) or not 0 <= window_s <= DAY_S / 2:
        raise ValueError(f"window_s must be in [0, {DAY_S / 2:g}] s, got {window_s!r}")
    if tz is not None and not isinstance(tz, tzinfo):
        raise ValueError(f"tz must be a datetime.tzinfo (the robot's time zone) or None (UTC days), got {tz!r}")
    saw = np.flatnonzero(m.person_s >= seen_s)                       # the minutes that SAW the person
    saw_start = m.minute[saw]
    saw_end = saw_start + MINUTE_S
    saw_or_none = np.append(saw, len(m))                             # len(m): no SAW minute at or after
    per_day, censored = [], 0
    for t_d in day_starts(t0, days, tz):
        # the day, before t0 (a day of 23 h ends at t0 after the clocks go forward); candidates end before it
        lo, hi = np.searchsorted(m.minute, [t_d, min(t_d + DAY_S, t0)], "left")
        if m._cum[hi] - m._cum[lo] < day_min_watched_s:
            continue                                                 # the day does not count
        a, b = np.searchsorted(saw_end, [t_d - window_s, t_d + window_s], "right")
        s = np.append(t_d, saw_end[a:b])                             # the candidate starts
        first = saw_or_none[np.searchsorted(saw_start, s, "left")]   # the first SAW minute at or after each
        out = first >= hi                                            # none in the day: censored
        begin = np.searchsorted(m.minute, np.minimum(s, t_d), "left")
        per_day.append(float(np.max(m._cum[np.where(out, hi, first)] - m._cum[begin])))
        censored += bool(out.any())
    usual = max(per_day) if len(per_day) >= learn_days else None
    return Usual(t0=t0, usual_s=usual, days=len(per_day), learn_days=learn_days, per_day=tuple(per_day),
                 censored=censored)


def day_starts(t0: float, days: int, tz: tzinfo | None = None) -> list[float]:
    """t_d for d = 1..``days`` (unix s, newest first): the wall-clock time of ``t0`` d days before in ``tz``
    (a DST change keeps the wall clock: t0 - t_d is then 23 or 25 h), or t0 - d * DAY_S when ``tz`` is None.
    The fraction of a second of ``t0`` is kept (datetime keeps microseconds)."""
    if tz is None:
        return [t0 - d * DAY_S for d in range(1, days + 1)]
    whole = math.floor(t0)
    here = datetime.fromtimestamp(whole, tz)
    return [(here - timedelta(days=d)).timestamp() + (t0 - whole) for d in range(1, days + 1)]


def _finite(name: str, x: float) -> float:
    try:
        v = float(x)
    except (TypeError, ValueError):
        v = math.nan
    if not math.isfinite(v):
        raise ValueError(f"{name} must be a finite unix time in seconds, got {x!r}")
    return v


def _count(name: str, x: int, what: str) -> int:
    if isinstance(x, bool) or not isinstance(x, Integral) or x < 1:
        raise ValueError(f"{name} ({what}) must be an integer >= 1, got {x!r}")
    return int(x)


def _check_seen(seen_s: float) -> None:
    if isinstance(seen_s, bool) or not isinstance(seen_s, Real) or not 0 < seen_s <= MINUTE_S:
        raise ValueError(f"seen_s must be in (0, {MINUTE_S:g}] s (a minute's person seconds), got {seen_s!r}")
