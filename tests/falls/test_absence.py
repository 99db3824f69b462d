"""Not seen for longer than usual (falls.absence): the vectorised model against a plain loop written from the
spec's words on random minute tables, and households whose routine is known."""

from __future__ import annotations

import bisect
import dataclasses
import math
import random
from datetime import UTC, datetime, timedelta
from zoneinfo import ZoneInfo

import numpy as np
import pytest

from posed.falls import SEEN_S, Minutes, Usual, last_seen, usual_absence, watched_between
from posed.falls.absence import DAY_MIN_WATCHED_S, DAY_S, WINDOW_S, day_starts

H = 3600.0
MIDNIGHT = datetime(2026, 3, 2, tzinfo=UTC).timestamp()   # a Monday, 00:00 UTC
BERLIN = ZoneInfo("Europe/Berlin")                        # CET/CEST: 2026-03-29 02:00 -> 03:00, 10-25 03:00 -> 02:00
ZONES = (None, UTC, BERLIN, ZoneInfo("Asia/Kolkata"))     # UTC days, UTC, a zone with DST, one with +05:30
SPRING = datetime(2026, 3, 26, tzinfo=UTC).timestamp()   # a few days before each change in 2026
AUTUMN = datetime(2026, 10, 22, tzinfo=UTC).timestamp()


# ---- the reference: the spec's words as a plain loop over a {minute: (watched_s, person_s)} table ----

def ref_table(rows) -> dict[float, tuple[float, float]]:
    """Rows cleaned one by one: a row that is not three numbers (None is NaN) or whose minute is not finite is
    dropped, counts that are NaN, infinite or negative are 0, the minute is its start, rows of one minute add
    up."""
    table: dict[float, list[float]] = {}
    for row in rows:
        try:
            minute, w, p = (math.nan if x is None else float(x) for x in row)
        except (TypeError, ValueError):
            continue
        if not math.isfinite(minute):
            continue
        start = math.floor(minute / 60) * 60.0
        acc = table.setdefault(start, [0.0, 0.0])
        acc[0] += w if math.isfinite(w) and w > 0 else 0.0
        acc[1] += p if math.isfinite(p) and p > 0 else 0.0
    return {k: (v[0], v[1]) for k, v in sorted(table.items())}


def ref_last_seen(table, before=None, seen_s=SEEN_S):
    found = None
    for minute, (_, p) in table.items():           # ascending
        if (before is None or minute < before) and p >= seen_s:
            found = minute + 60
    return found


def ref_watched_between(table, start, end):
    return sum(w for minute, (w, _) in table.items() if start <= minute < end)


def ref_day_start(t0, d, tz):
    """The same wall-clock time d days before t0 in tz (None: d days of 24 h); the fraction of a second kept."""
    if tz is None:
        return t0 - d * 86400
    whole = math.floor(t0)
    return (datetime.fromtimestamp(whole, tz) - timedelta(days=d)).timestamp() + (t0 - whole)


def ref_usual(table, t0, days, learn_days, seen_s=SEEN_S, day_min=DAY_MIN_WATCHED_S, tz=None, window_s=WINDOW_S):
    past = [(minute, w, p) for minute, (w, p) in table.items() if minute < t0]    # ascending
    per_day, censored = [], 0
    for d in range(1, days + 1):
        t_d = ref_day_start(t0, d, tz)
        end = min(t_d + 86400, t0)
        if sum(w for minute, w, _ in past if t_d <= minute < end) < day_min:
            continue                                   # the day does not count
        # every time the person went out of view within window_s of t_d (the end of a minute that saw them)
        starts = [t_d] + [minute + 60 for minute, _, p in past
                          if p >= seen_s and t_d - window_s < minute + 60 <= t_d + window_s]
        values, away = [], False
        for s in starts:
            # from then, or from t_d if then was later, until the first minute that saw them at or after then
            value, back = 0.0, False
            for minute, w, p in past[bisect.bisect_left(past, (min(s, t_d),)):]:
                if minute >= end:
                    break                              # not back within the day: to its end (censored)
                if minute >= s and p >= seen_s:
                    back = True
                    break
                value += w
            away = away or not back
            values.append(value)
        censored += away
        per_day.append(max(values))
    usual = max(per_day) if len(per_day) >= learn_days else None
    return usual, per_day, censored


def random_rows(rng: random.Random, span_days: int):
    """Minutes over ``span_days`` days from a random (minute-aligned) start: runs watched and not, some
    minutes watched with nobody in view, some with a spurious frame, some seen; then duplicates, damaged rows,
    shuffled."""
    base = rng.choice((MIDNIGHT, SPRING, AUTUMN)) + 60 * rng.randrange(0, 1440)   # with DST changes
    n = span_days * 1440
    rows = []
    i = 0
    while i < n:
        run = rng.randint(1, 600)
        if rng.random() < rng.choice((0.15, 0.5)):     # not watched: no rows at all
            i += run
            continue
        p_seen = rng.choice((0.0, 0.001, 0.01, 0.2))
        for k in range(i, min(i + run, n)):
            w = rng.choice((60.0, 60.0, 59.5, 30.0, 0.0))        # 0: a paused minute still has a row
            u = rng.random()
            p = rng.uniform(SEEN_S, w) if (u < p_seen and w >= SEEN_S) else \
                (SEEN_S if u < p_seen * 1.5 and w >= SEEN_S else rng.choice((0.0, 0.0, 0.2, 1.99)))
            rows.append((base + 60.0 * k, w, min(p, w)))
        i += run
    for _ in range(rng.randint(0, 20)):                 # a minute written in two flushes: the counts add up
        j = rng.randrange(len(rows)) if rows else None
        if j is not None:
            minute, w, p = rows[j]
            rows[j] = (minute, w / 2, p / 2)
            rows.append((minute + rng.choice((0.0, 17.0)), w / 2, p / 2))   # same minute, not its start
    rows += [(math.nan, 60.0, 60.0), (base + 60, math.nan, 5.0), (base + 120, 60.0, -0.5),
             (base + 180, math.inf, math.nan), ("x", 1.0, 2.0), (base + 240, 30.0), None][:rng.randint(0, 7)]
    rng.shuffle(rows)
    return base, rows


@pytest.mark.parametrize("seed", range(40))
def test_vectorised_model_matches_the_spec_loop_on_random_tables(seed):
    rng = random.Random(seed)
    days = rng.randint(1, 5)
    base, rows = random_rows(rng, days + 1)
    m = Minutes.from_rows(rows)
    table = ref_table(rows)
    assert m.minute.tolist() == list(table)
    assert m.watched_s.tolist() == pytest.approx([w for w, _ in table.values()])
    assert m.person_s.tolist() == pytest.approx([p for _, p in table.values()])
    end = base + (days + 1) * DAY_S
    t0s = [end, end - 60 * rng.randrange(0, 600), end - rng.uniform(0, 2 * H), rng.uniform(base, end)]
    for t0 in t0s:
        seen_s = rng.choice((SEEN_S, SEEN_S, 0.2, 30.0))
        day_min = rng.choice((DAY_MIN_WATCHED_S, 0.0, rng.uniform(0, DAY_S)))
        learn = rng.randint(1, days + 1)
        tz = rng.choice(ZONES)
        window = rng.choice((WINDOW_S, WINDOW_S, 2 * H, 0.0, 60.0 * rng.randrange(0, 720), rng.uniform(0, DAY_S / 2),
                             rng.uniform(0, 60)))
        got = usual_absence(m, t0, days=days, learn_days=learn, seen_s=seen_s, day_min_watched_s=day_min,
                            tz=tz, window_s=window)
        usual, per_day, censored = ref_usual(table, t0, days, learn, seen_s, day_min, tz, window)
        assert day_starts(t0, days, tz) == pytest.approx([ref_day_start(t0, d, tz) for d in range(1, days + 1)],
                                                         abs=1e-6)
        assert got.per_day == pytest.approx(per_day, abs=1e-6)
        assert got.days == len(per_day) and got.censored == censored and got.learn_days == learn
        assert (got.usual_s is None) == (usual is None) and got.learning == (usual is None)
        if usual is not None:
            assert got.usual_s == pytest.approx(usual, abs=1e-6)
        assert last_seen(m, t0, seen_s) == ref_last_seen(table, t0, seen_s)
        a, b = sorted((rng.uniform(base - H, end + H), rng.uniform(base - H, end + H)))
        assert watched_between(m, a, b) == pytest.approx(ref_watched_between(table, a, b), abs=1e-6)
        assert watched_between(m, b, a) == (0.0 if a < b else watched_between(m, a, b))
        if len(table) > 1:                            # on minute starts: the start's minute in, not the end's
            a, b = sorted(rng.sample(list(table), 2))
            assert watched_between(m, a, b) == pytest.approx(ref_watched_between(table, a, b), abs=1e-6)
    assert last_seen(m) == ref_last_seen(table)


def test_the_random_tables_reach_every_case():
    """The cases the comparison above is meant to cover do occur in its tables: days not counted, censored
    days, days seen in their first minute, learning and not, days the window makes longer, days of 23 and
    25 h in Berlin."""
    seen = {"not counted": 0, "censored": 0, "first minute": 0, "learning": 0, "usual": 0, "window": 0,
            "23 h": 0, "25 h": 0}
    for seed in range(40):
        rng = random.Random(seed)
        days = rng.randint(1, 5)
        base, rows = random_rows(rng, days + 1)
        table = ref_table(rows)
        for t0 in (base + (days + 1) * DAY_S, base + (days + 1) * DAY_S - 7 * H):
            usual, per_day, censored = ref_usual(table, t0, days, 2)
            seen["not counted"] += len(per_day) < days
            seen["censored"] += censored
            seen["first minute"] += 0.0 in per_day
            seen["learning" if usual is None else "usual"] += 1
            seen["window"] += per_day != ref_usual(table, t0, days, 2, window_s=0.0)[1]
            starts = [t0] + [ref_day_start(t0, d, BERLIN) for d in range(1, days + 1)]
            lengths = {round(a - b) for a, b in zip(starts, starts[1:], strict=False)}
            seen["23 h"] += 23 * 3600 in lengths
            seen["25 h"] += 25 * 3600 in lengths
    assert all(v > 0 for v in seen.values()), seen


# ---- households ----

def at(day: int, hh: float) -> float:
    """Unix time of ``hh`` hours (UTC) on day ``day`` after MIDNIGHT."""
    return MIDNIGHT + day * DAY_S + hh * H


def routine_day(day: int, seen_minutes, watched=(0.0, 24.0)) -> dict[float, tuple[float, float]]:
    """One day's minutes, watched (whole minutes, 60 s) from ``watched[0]`` to ``watched[1]`` h, the person in
    view for 8 s in each of ``seen_minutes`` (hours of the day) and never else."""
    seen = {round(at(day, h)) for h in seen_minutes}
    first, last = int(watched[0] * 60), int(watched[1] * 60)
    return {at(day, k / 60): (60.0, 8.0 if round(at(day, k / 60)) in seen else 0.0)
            for k in range(first, last)}


def to_minutes(table) -> Minutes:
    return Minutes.from_rows((k, w, p) for k, (w, p) in table.items())


AWAKE = [7.5] + [float(h) for h in range(8, 22)] + [21 + 59 / 60]   # in view at 07:30, every hour, 21:59


def household(days: int = 16, changes: dict | None = None) -> dict:
    """``days`` days of the routine: seen at 07:30, every hour 08:00-21:00 and at 21:59; asleep out of view
    from 22:00 to 07:30; the camera watching all day since it was set up at 22:00 on day 0. ``changes``:
    day -> that day's table instead."""
    table = {}
    for d in range(days):
        table.update((changes or {}).get(d, routine_day(d, AWAKE)))
    return {k: v for k, v in table.items() if k >= at(0, 22.0)}


def test_a_routine_of_fourteen_nights_sets_the_usual_at_nine_and_a_half_hours():
    m = to_minutes(household(16))
    t0 = last_seen(m, before=at(15, 23.0))
    assert t0 == at(15, 22.0)                      # the 21:59 minute ended at 22:00
    u = usual_absence(m, t0)
    assert u.days == 14 and u.censored == 0 and not u.learning
    assert u.per_day == pytest.approx([9.5 * H] * 14)   # 22:00 to 07:30, every night
    assert u.usual_s == pytest.approx(9.5 * H)
    assert u.notice_after_s(1 * H) == pytest.approx(10.5 * H)
    # tonight the camera watches on and nobody comes: no notice at 10 h, a notice once 10.5 h have passed
    tonight = {**household(16), **routine_day(16, [], watched=(0.0, 24.0))}
    m2 = to_minutes(tonight)
    assert watched_between(m2, t0, t0 + 10 * H) == pytest.approx(10 * H)
    assert watched_between(m2, t0, t0 + 10 * H) <= u.notice_after_s(H)
    assert watched_between(m2, t0, t0 + 10.5 * H + 60) > u.notice_after_s(H)


def test_the_usual_from_midday_runs_to_the_walk_after_the_window():
    """The price of the window: out of view at 13:01 on past days (within 1.5 h), back at 14:00, counts from 12:01;
    out of view at 14:01 (2 h later) does not count."""
    m = to_minutes(household(16))
    t0 = last_seen(m, before=at(15, 12.5))
    assert t0 == at(15, 12.0 + 1 / 60)             # seen in the 12:00 minute
    u = usual_absence(m, t0)
    assert u.usual_s == pytest.approx(H + 59 * 60)          # 12:01 to 14:00
    assert u.notice_after_s(H) == pytest.approx(2 * H + 59 * 60)
    assert usual_absence(m, t0, window_s=2 * H).usual_s == pytest.approx(2 * H + 59 * 60)   # 2 h: to 15:00
    assert usual_absence(m, t0, window_s=0.0).usual_s == pytest.approx(59 * 60)   # no window: to the 13:00 walk


def test_a_person_always_in_view_at_half_past_eight_in_the_evening_waits_for_the_morning():
    """In view every evening at 20:30 but to bed at 22:00, 1.5 h later, within the window: out of view at 20:30
    cannot be told from going to bed 1.5 h early, so the usual runs to the 07:30 wake-up."""
    tv = [19 + k / 60 for k in range(120)]          # watching television in view 19:00-21:00, every minute
    table = household(16, {d: routine_day(d, AWAKE + tv) for d in range(16)})
    m = to_minutes(table)
    u = usual_absence(m, at(15, 20.5))
    assert u.days == 14 and u.usual_s == pytest.approx(11 * H)         # 20:30 to 07:30
    assert u.notice_after_s(H) == pytest.approx(12 * H)
    old = usual_absence(m, at(15, 20.5), window_s=0.0)                  # no window: back at once
    assert old.usual_s == pytest.approx(0.0) and old.notice_after_s(H) == pytest.approx(H)
    # from 20:00, 2 h before bedtime, going to bed is outside the window: to the 21:59 sighting after 21:01
    assert usual_absence(m, at(15, 20.0)).usual_s == pytest.approx(H + 59 * 60)


def test_learning_with_three_days():
    m = to_minutes(household(4))
    u = usual_absence(m, at(3, 22.0), days=14, learn_days=7)
    assert u.days == 3 and u.learning and u.usual_s is None and u.notice_after_s(H) is None
    assert u.per_day == pytest.approx([9.5 * H] * 3)
    assert not usual_absence(m, at(3, 22.0), days=14, learn_days=3).learning
    assert usual_absence(m, at(3, 22.0), days=2, learn_days=3).learning    # more to learn than looked at
    nothing = usual_absence(Minutes.from_rows([]), at(3, 22.0), learn_days=1)   # a new install
    assert nothing.learning and nothing.days == 0 and nothing.per_day == ()


def test_a_day_the_daemon_was_off_does_not_count():
    # window d = 5 (from 22:00 of day 10 to 22:00 of day 11): the daemon ran only 22:00-09:00 and saw nobody,
    # 11 h watched: had it counted, the usual would be 11 h
    off = {k: (60.0, 0.0) for k in np.arange(at(10, 22.0), at(11, 9.0), 60.0)}
    table = household(16)
    for k in np.arange(at(10, 22.0), at(11, 22.0), 60.0):
        table.pop(k)
    table.update(off)
    m = to_minutes(table)
    u = usual_absence(m, at(15, 22.0))
    assert watched_between(m, at(10, 22.0), at(11, 22.0)) == pytest.approx(11 * H)
    assert 11 * H < DAY_MIN_WATCHED_S
    assert u.days == 13 and u.censored == 0 and u.usual_s == pytest.approx(9.5 * H)
    # the same 11 h with the half-day rule off would have counted
    assert usual_absence(m, at(15, 22.0), day_min_watched_s=0.0).usual_s == pytest.approx(11 * H)
    # a day watched just half the day counts
    half = {k: (60.0, 0.0) for k in np.arange(at(10, 22.0), at(11, 10.0), 60.0)}
    for k in np.arange(at(10, 22.0), at(11, 9.0), 60.0):
        table.pop(k)
    table.update(half)
    assert usual_absence(to_minutes(table), at(15, 22.0)).days == 14


def test_a_day_away_is_censored_and_only_makes_the_usual_larger():
    base = usual_absence(to_minutes(household(16)), at(15, 22.0))
    for d in (2, 8, 14):                            # the window from 22:00 of day d to 22:00 of day d + 1
        table = household(16)
        for k in np.arange(at(d, 22.0), at(d + 1, 22.0), 60.0):
            table[k] = (60.0, 0.0)                 # the camera watched an empty flat
        u = usual_absence(to_minutes(table), at(15, 22.0))
        assert u.censored == 1 and u.days == 14
        assert u.usual_s == pytest.approx(DAY_S) and u.usual_s >= base.usual_s
        assert u.per_day[14 - d] == pytest.approx(DAY_S)     # newest first: d = 15 - day
        assert sorted(u.per_day)[:-1] == pytest.approx(sorted(base.per_day)[:-1])
    # away for the morning only (back at 11:00 instead of 07:30): a larger usual, not censored
    late = routine_day(9, [11.0] + [float(h) for h in range(12, 22)] + [21 + 59 / 60])
    u = usual_absence(to_minutes(household(16, {9: late})), at(15, 22.0))
    assert u.censored == 0 and u.usual_s == pytest.approx(13 * H)


def test_unwatched_minutes_never_add_to_the_absence():
    # every night the camera is off (or paused) from 00:00 to 02:00: 7.5 h of the 9.5 h are watched
    table = household(17)
    for d in range(1, 17):
        for k in np.arange(at(d, 0.0), at(d, 1.0), 60.0):
            table.pop(k)                           # no rows: the daemon was off
        for k in np.arange(at(d, 1.0), at(d, 2.0), 60.0):
            table[k] = (0.0, 0.0)                  # rows with nothing watched: paused
    m = to_minutes(table)
    u = usual_absence(m, at(15, 22.0))
    assert u.days == 14 and u.usual_s == pytest.approx(7.5 * H)
    assert watched_between(m, at(15, 22.0), at(16, 3.0)) == pytest.approx(3 * H)   # 22-24 and 02-03


def early_night(bedtime: float) -> tuple[Minutes, float]:
    """The household of 17 days, on day 15 to bed at ``bedtime`` (h): last seen in the minute before it; the
    minutes and that last sighting (asserted to be at the bedtime)."""
    day = routine_day(15, [7.5] + [float(h) for h in range(8, 21) if h < bedtime] + [bedtime - 1 / 60])
    m = to_minutes(household(17, {15: day}))
    t0 = last_seen(m, before=at(15, 23.0))
    assert t0 == at(15, bedtime)
    return m, t0


@pytest.mark.parametrize("bedtime,without", [(21.0, 0.0), (20.5, 30 * 60)])
def test_an_early_night_within_one_and_a_half_hours_waits_for_the_usual_wake_up(bedtime, without):
    """To bed at 21:00 (1 h early) or 20:30 (1.5 h, the window's edge), earlier than on any of the last 14
    days: on past days the person went out of view at 22:00, within 1.5 h, and was back at 07:30, so the usual
    runs from the bedtime to 07:30 and the notice waits for the usual wake-up + 1 h. Without the window: to the
    21:00 walk on past days, and a notice at 22:00 while asleep."""
    m, t0 = early_night(bedtime)
    u = usual_absence(m, t0)
    night = at(16, 7.5) - t0                                    # 10.5 h, 11 h
    assert u.days == 14 and u.per_day == pytest.approx([night] * 14)    # bedtime to 07:30
    assert t0 + u.notice_after_s(H) == pytest.approx(at(16, 8.5))        # the usual wake-up + 1 h
    back = last_seen(m, before=at(16, 8.0)) - 60                          # up at 07:30 as usual
    assert watched_between(m, t0, back) == pytest.approx(night)
    assert watched_between(m, t0, back) < u.notice_after_s(H)
    old = usual_absence(m, t0, window_s=0.0)
    assert old.usual_s == pytest.approx(without) and t0 + old.notice_after_s(H) == pytest.approx(at(15, 22.0))


@pytest.mark.parametrize("bedtime,usual", [(20.0, H + 59 * 60), (19.0, 2 * H)])
def test_an_early_night_more_than_one_and_a_half_hours_earlier_than_ever_gives_a_notice(bedtime, usual):
    """A limit (docs/falls.md): to bed at 20:00 (2 h early) or 19:00 (3 h), earlier than on any past day by more
    than the window; going to bed at 22:00 is not within 1.5 h, so the usual is the time to a walk through the
    room (from 20:00: the 21:59 sighting after 21:01; from 19:00: the 21:00 walk after 20:01) and the notice
    comes while asleep (at 22:59, 22:00)."""
    m, t0 = early_night(bedtime)
    u = usual_absence(m, t0)
    assert u.usual_s == pytest.approx(usual)
    assert t0 + u.notice_after_s(H) == pytest.approx(at(15, bedtime + 1) + usual)   # asleep till 07:30
    assert t0 + u.notice_after_s(H) < at(16, 7.5)


def test_an_outing_that_began_up_to_one_and_a_half_hours_apart_counts_whole():
    """Today out of view from 14:00 to 17:00. On one past day (day 10) the same 3 h outing began an hour later
    (or earlier, or 1.5 h later, the window's edge): it counts whole, from 14:00 to 18:00 (from 13:00 to 16:00;
    from 14:00 to 19:00, the first walk after it), and today is quiet. Begun 2 h later, it is outside the window."""
    def out(day, leave, back):                                  # the hourly walks, out of view leave..back
        return routine_day(day, [h for h in AWAKE if not leave <= h < back] + [leave - 1 / 60])

    for leave, usual in ((15.0, 4 * H), (13.0, 3 * H), (15.5, 5 * H), (16.0, 2 * H)):
        m = to_minutes(household(17, {10: out(10, leave, leave + 3), 15: out(15, 14.0, 17.0)}))
        t0 = last_seen(m, before=at(15, 16.0))
        assert t0 == at(15, 14.0)
        absent = watched_between(m, t0, last_seen(m, before=at(15, 18.0)) - 60)
        assert absent == pytest.approx(3 * H)
        u = usual_absence(m, t0)
        assert u.usual_s == pytest.approx(usual)
        assert (absent < u.notice_after_s(H)) == (leave != 16.0)    # 2 h later: the notice due as they are back
    # without that day: out of view at 15:01 on past days, back at 16:00 (2 h from 14:00): the notice at 3 h
    m = to_minutes(household(17, {15: out(15, 14.0, 17.0)}))
    base = usual_absence(m, t0)
    assert base.usual_s == pytest.approx(2 * H) and base.notice_after_s(H) == pytest.approx(3 * H)
    assert usual_absence(m, t0, window_s=0.0).usual_s == pytest.approx(0.0)   # no window: seen at 14:00 every day


# ---- clock changes: a routine kept by the local clock ----

def local_routine(first: datetime, days: int, zone=BERLIN) -> Minutes:
    """``days`` days from ``first`` (local midnight) of the household routine by the local clock of ``zone``: in
    view at 07:30, every hour 08:00-21:00 and at 21:59, asleep out of view 22:00-07:30; every minute watched."""
    seen = {(7, 30), (21, 59)} | {(h, 0) for h in range(8, 22)}
    start = first.replace(tzinfo=zone).timestamp()
    end = (first + timedelta(days=days)).replace(tzinfo=zone).timestamp()
    rows = []
    for minute in np.arange(start, end, 60.0):
        local = datetime.fromtimestamp(minute, zone)
        rows.append((minute, 60.0, 8.0 if (local.hour, local.minute) in seen else 0.0))
    return Minutes.from_rows(rows)


def local(y, mo, d, h, mi=0) -> float:
    return datetime(y, mo, d, h, mi, tzinfo=BERLIN).timestamp()


@pytest.mark.parametrize("change,nights", [
    # spring (29 March): the night of the change is an hour shorter, the next nights are usual
    ((2026, 3, 29), [((2026, 3, 28), 8.5 * H, 9.5 * H), ((2026, 3, 29), 9.5 * H, 9.5 * H),
                     ((2026, 3, 30), 9.5 * H, 9.5 * H)]),
    # autumn (25 October): the night of the change is an hour longer, and sets the usual for two weeks
    ((2026, 10, 25), [((2026, 10, 25), 9.5 * H, 10.5 * H), ((2026, 10, 26), 9.5 * H, 10.5 * H)]),
])
def test_the_nights_after_the_clocks_change_wait_for_the_usual_wake_up(change, nights):
    """Local days (tz): from 22:00 local, on each night after a change, no notice before the usual 07:30."""
    y, mo, d = change
    m = local_routine(datetime(y, mo, d) - timedelta(days=18), 24)
    for (ny, nmo, nd), night, usual in nights:
        t0 = last_seen(m, before=local(ny, nmo, nd, 23))
        assert t0 == local(ny, nmo, nd, 22)
        wake = (datetime(ny, nmo, nd, 7, 30, tzinfo=BERLIN) + timedelta(days=1)).timestamp()
        assert watched_between(m, t0, wake) == pytest.approx(night)
        u = usual_absence(m, t0, tz=BERLIN)
        assert u.days == 14 and u.usual_s == pytest.approx(usual)
        assert watched_between(m, t0, wake) < u.notice_after_s(H)      # quiet until the wake-up and after


def test_the_night_the_clocks_go_back_uses_up_the_margin():
    """A limit (docs/falls.md): to bed at 22:00 summer time, up at 07:30 winter time, 10.5 h; the 14 nights
    before were 9.5 h: the wake-up comes just as the notice is due (usual + 1 h)."""
    m = local_routine(datetime(2026, 10, 7), 24)
    t0 = local(2026, 10, 24, 22)
    u = usual_absence(m, t0, tz=BERLIN)
    assert u.usual_s == pytest.approx(9.5 * H)
    wake = datetime(2026, 10, 25, 7, 30, tzinfo=BERLIN).timestamp()
    assert wake - t0 == pytest.approx(10.5 * H) == u.notice_after_s(H)


def test_the_day_before_the_clocks_go_forward_is_23_h_long():
    """From 22:00 local on 29 March, yesterday began at 22:00 CET, 23 h before: a day away (nobody seen, every
    minute watched until after t0) is censored at those 23 h, not 24; seen at 23:00 and 21:00, it is 22 h."""
    t0 = local(2026, 3, 29, 22)
    t1 = local(2026, 3, 28, 22)
    assert t0 - t1 == 23 * H
    rows = [(k, 60.0, 0.0) for k in np.arange(t1 - 4 * H, t0 + 3 * H, 60.0)]
    u = usual_absence(Minutes.from_rows(rows), t0, days=1, learn_days=1, tz=BERLIN)
    assert u.per_day == pytest.approx((23 * H,)) and u.censored == 1
    seen = {t1 + H, t0 - H, t0 + H / 2}                      # 23:00 CET, 21:00 CEST, and after t0 (not used)
    rows = [(k, w, 8.0 if k in seen else p) for k, w, p in rows]
    u = usual_absence(Minutes.from_rows(rows), t0, days=1, learn_days=1, tz=BERLIN)
    assert u.per_day == pytest.approx((22 * H,)) and u.censored == 0     # out of view 23:01, back 21:00


def test_utc_days_and_the_spring_change():
    """Without the zone (UTC days) t_d moves an hour against the routine; the window still reaches 22:00."""
    m = local_routine(datetime(2026, 3, 11), 24)
    t0 = local(2026, 3, 29, 22)                                 # 20:00 UTC: 21:00 CET on the days before
    u = usual_absence(m, t0)
    assert u.usual_s == pytest.approx(10.5 * H)                 # 21:00 CET to 07:30 CET
    assert day_starts(t0, 2) == [t0 - DAY_S, t0 - 2 * DAY_S]
    assert day_starts(t0, 2, BERLIN) == [local(2026, 3, 28, 22), local(2026, 3, 27, 22)]   # 23 and 47 h before


def test_the_window_and_its_bounds():
    """One past day from t_1 = t0 - 1 day, every minute watched: the ends of SAW minutes in (t_1 - w, t_1 + w]
    are the candidates, and t_1 itself (the lower bound is pinned by the random comparison)."""
    t1 = 100 * DAY_S
    t0 = t1 + DAY_S

    def usual(seen, t_1=t1, **kw):
        rows = [(k, 60.0, 8.0 if k in seen else 0.0) for k in np.arange(t1 - DAY_S, t0 + H, 60.0)]
        return usual_absence(Minutes.from_rows(rows), t_1 + DAY_S, days=1, learn_days=1, **kw).usual_s

    assert WINDOW_S == 1.5 * H
    # out of view exactly 1.5 h later (the end of the minute before), back 5 h after t_1: 5 h; 1 s less: not counted
    seen = {t1, t1 + WINDOW_S - 60, t1 + 5 * H}
    assert usual(seen) == pytest.approx(5 * H)
    assert usual(seen, window_s=WINDOW_S - 1) == pytest.approx(WINDOW_S - 60)   # out of view t_1 + 60, back then
    # t_1 itself: in the middle of a minute, the minute before seen (its end within 10 s), the next not
    assert usual({t1 - 60, t1, t1 + H}, t_1=t1 + 5, window_s=10.0) == pytest.approx(H - 60)


def test_seen_means_two_seconds_in_a_minute():
    rows = [(0.0, 60.0, 0.2), (60.0, 60.0, 1.99), (120.0, 60.0, 2.0), (180.0, 60.0, 1.0), (240.0, 60.0, 0.0)]
    m = Minutes.from_rows(rows)
    assert last_seen(m) == 180.0                    # the 2 s minute, ended
    assert last_seen(m, before=120.0) is None       # spurious frames are not a sighting
    assert last_seen(m, before=120.5) == 180.0      # the minute starting before 120.5 counts
    assert last_seen(m, seen_s=0.1) == 240.0
    assert last_seen(Minutes.from_rows([])) is None


def test_minutes_clean_damaged_rows_and_are_frozen():
    m = Minutes.from_rows([(120, 30, 1), (60, 60, 5), (125, 30, 1.5), (float("nan"), 60, 60),
                           (180, -0.5, None),
                           (240, float("inf"), 3), ("bad", 1, 2), (300, 1), None, (360, "7", "2")])
    assert m.minute.tolist() == [60, 120, 180, 240, 360]
    assert m.watched_s.tolist() == [60, 60, 0, 0, 7]
    assert m.person_s.tolist() == [5, 2.5, 0, 3, 2]
    assert len(m) == 5 and m.minute.dtype == np.float64
    # the same rows without those that are not three numbers are read in one go: the same minutes
    numeric = Minutes.from_rows([(120, 30, 1), (60, 60, 5), (125, 30, 1.5), (float("nan"), 60, 60),
                                 (180, -0.5, None), (240, float("inf"), 3), (360, "7", "2")])
    for name in ("minute", "watched_s", "person_s"):
        assert getattr(numeric, name).tolist() == getattr(m, name).tolist()
    with pytest.raises(ValueError):
        m.watched_s[0] = 1.0                       # read-only
    with pytest.raises(dataclasses.FrozenInstanceError):
        m.minute = np.zeros(5)
    # rows of six columns (the whole `watched` row) are not three: dropped, not misread
    assert len(Minutes.from_rows([(60, 1, 1, 1, 60, 5)])) == 0


def test_minutes_made_directly_must_be_clean():
    with pytest.raises(ValueError, match="strictly ascending"):
        Minutes(np.array([120.0, 60.0]), np.ones(2), np.ones(2))
    with pytest.raises(ValueError, match="strictly ascending"):
        Minutes(np.array([60.0, 60.0]), np.ones(2), np.ones(2))
    with pytest.raises(ValueError, match="person_s has 1 values for 2 minutes"):
        Minutes(np.array([0.0, 60.0]), np.ones(2), np.ones(1))
    with pytest.raises(ValueError, match="watched_s must be >= 0"):
        Minutes(np.array([0.0]), np.array([-1.0]), np.zeros(1))
    with pytest.raises(ValueError, match="minute must be finite"):
        Minutes(np.array([np.nan]), np.zeros(1), np.zeros(1))
    with pytest.raises(ValueError, match="one-dimensional"):
        Minutes(np.zeros((2, 2)), np.zeros(2), np.zeros(2))


@pytest.mark.parametrize("kwargs,match", [
    ({"days": 0}, r"days \(the past days looked at\) must be an integer >= 1, got 0"),
    ({"days": -3}, r"days .* >= 1"),
    ({"days": 1.5}, r"days .* integer >= 1"),
    ({"days": True}, r"days .* integer >= 1"),
    ({"learn_days": 0}, r"learn_days .* must be an integer >= 1, got 0"),
    ({"seen_s": 0.0}, r"seen_s must be in \(0, 60\] s"),
    ({"seen_s": 61.0}, r"seen_s must be in \(0, 60\] s"),
    ({"day_min_watched_s": -1.0}, r"day_min_watched_s must be in \[0, 86400\] s"),
    ({"day_min_watched_s": math.nan}, r"day_min_watched_s must be in \[0, 86400\] s"),
    ({"t0": math.nan}, r"t0 must be a finite unix time"),
    ({"window_s": -1.0}, r"window_s must be in \[0, 43200\] s"),
    ({"window_s": 43201.0}, r"window_s must be in \[0, 43200\] s"),
    ({"window_s": math.inf}, r"window_s must be in \[0, 43200\] s"),
    ({"tz": "Europe/Berlin"}, r"tz must be a datetime.tzinfo"),
])
def test_bad_arguments_name_the_valid_range(kwargs, match):
    m = to_minutes(household(2))
    args = {"t0": at(2, 22.0), **kwargs}
    with pytest.raises(ValueError, match=match):
        usual_absence(m, **args)


def test_bad_margins_and_times_name_the_valid_range():
    u = Usual(t0=0.0, usual_s=3600.0, days=7, learn_days=7, per_day=(3600.0,) * 7, censored=0)
    assert u.notice_after_s(0) == 3600.0 and u.notice_after_s(np.float64(1800.0)) == 5400.0
    for bad in (-1.0, math.inf, math.nan, "1"):
        with pytest.raises(ValueError, match="margin_s must be a finite number of seconds >= 0"):
            u.notice_after_s(bad)
    m = to_minutes(household(1))
    with pytest.raises(ValueError, match="before must be a finite unix time"):
        last_seen(m, before=math.nan)
    with pytest.raises(ValueError, match=r"seen_s must be in \(0, 60\]"):
        last_seen(m, seen_s=-1)
    with pytest.raises(ValueError, match="end must be a finite unix time"):
        watched_between(m, 0.0, math.inf)
