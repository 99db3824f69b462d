"""The "not seen for longer than usual" notice on SIMULATED households (``posed bench absence``): a model, not a
measurement. No recordings of real days at home exist here; what a deployer needs to know (how often the
notice comes when nothing happened, how long after a fall out of view it comes) is estimated on made-up
routines whose parameters are stated, each with its source or marked as an assumption (docs/bench/absence.md).

Simulated per household (seeded ``numpy`` Generator), at minute resolution, the per-minute table posed's history
writes (``minute``, ``watched_s``, ``person_s``; posed watches all day: ``watched_s`` 60 in every minute):

* a usual wake time and bedtime per household, each day's drawn around them (normal; the within-person SD of
  time in bed, 1.31 h, Knutson et al. 2007, split equally between bedtime and wake time: an assumption);
  asleep out of view (the camera is not in the bedroom);
* awake: passes through the camera's room as a Poisson process (1-4 visits an hour, per household; dwell
  exponential, a few minutes), meals in view and on some evenings television in view before bed;
* on some days one outing away from home (no sightings), of 0.5-6 h;
* falls: on a copy of the history up to the fall (as if it were the household's first), at a random awake time
  at home while out of view, the person never seen again until found 24 h later.

Each absence (from the end of a minute that SAW the person, ``SEEN_S``, to the next such minute) is judged as the
daemon judges it (daemon/history/absence.py): the usual computed once at its start ``t0`` with the real
:func:`posed.falls.absence.usual_absence`, a notice when the watched seconds since ``t0`` exceed usual + margin.
The rule's constants (window 1.5 h, margin 1 h, 14 days, 7 to learn) were set from studies before this
benchmark; it reports them, it does not tune them.
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass

import numpy as np

from posed.bench.machine import machine
from posed.falls.absence import DAY_S, MINUTE_S, SEEN_S, WINDOW_S, Minutes, last_seen, usual_absence
from posed.falls.config import FallsConfig

SEED = 0
BASE_UNIX = 1767571200.0          # 2026-01-05 00:00 UTC, the first simulated day (UTC days: tz None)
MONTH_DAYS = 30.44                # days in an average month
HOUR_S = 3600.0
FOUND_AFTER_S = 24 * HOUR_S       # a fallen person out of view is found this long after the fall
WITHIN_H = (2, 4, 8, 12)          # "noticed within" columns
VARIANTS = (("window 1.5 h (default)", WINDOW_S), ("window off (0)", 0.0), ("window 2 h", 2 * HOUR_S))


@dataclass(frozen=True)
class Params:
    """The simulation's parameters (hours unless said); docs/bench/absence.md gives each one's source."""

    wake_mean_h: tuple[float, float] = (6.5, 8.5)       # a household's usual wake time, uniform between (assumption)
    bed_mean_h: tuple[float, float] = (21.0, 23.5)      # ... and usual bedtime (assumption)
    time_in_bed_sd_h: float = 1.31                      # within-person SD of time in bed (Knutson et al. 2007)
    visits_per_h: tuple[float, float] = (1.0, 4.0)      # passes through the camera's room, per household (assumption)
    dwell_mean_min: float = 3.0                          # a pass's time in view, exponential (assumption) ...
    dwell_min_s: float = 5.0                             # ... at least this (a walk through the view)
    dwell_max_min: float = 30.0                          # ... at most this
    meal_min: tuple[float, float] = (20.0, 45.0)         # breakfast, lunch, dinner in view, minutes (assumption)
    tv_evening_p: tuple[float, float] = (0.2, 0.8)      # per household, share of evenings with TV in view (assumption)
    tv_h: tuple[float, float] = (1.0, 2.5)              # its length, ending 0-30 min before bed (assumption)
    outing_p: tuple[float, float] = (0.3, 0.9)          # per household, share of days with an outing (mean 0.6;
    #                                                     about 10.4 trips in 14 days were measured: Mochcovitch 2025)
    outing_median_h: float = 2.0                        # outing length, lognormal around this median (assumption)
    outing_sigma: float = 0.5                            # ... its log SD (assumption)
    outing_h: tuple[float, float] = (0.5, 6.0)          # ... clipped to these (assumption)
    learn_only_days: int = 14                            # the first days only teach the routine (none judged)
    falls_per_household: int = 4                         # falls simulated per household, each on its own copy


@dataclass(frozen=True)
class Plan:
    households: int = 200
    days: int = 60
    seed: int = SEED
    margin_s: float = float(FallsConfig().absence_margin_h) * HOUR_S
    absence_days: int = int(FallsConfig().absence_days)
    learn_days: int = int(FallsConfig().absence_learn_days)
    params: Params = Params()


@dataclass
class Household:
    """One simulated household: its minutes table and what was really happening (for the labels)."""

    minute: np.ndarray        # minute starts, unix s
    watched_s: np.ndarray
    person_s: np.ndarray
    view: np.ndarray          # (k, 2) merged in-view intervals, unix s
    sleep: np.ndarray         # (k, 2) asleep intervals
    away: np.ndarray          # (k, 2) outings
    awake: np.ndarray         # (days, 2) each day's [wake, bed)
    info: dict


def _merge(iv: np.ndarray) -> np.ndarray:
    """Sorted, non-overlapping union of intervals (k, 2)."""
    if len(iv) == 0:
        return iv.reshape(0, 2)
    iv = iv[np.argsort(iv[:, 0])]
    ends = np.maximum.accumulate(iv[:, 1])
    new = np.concatenate(([True], iv[1:, 0] > ends[:-1]))
    starts = iv[new, 0]
    last = np.flatnonzero(np.append(new[1:], True))
    return np.stack([starts, ends[last]], axis=1)


def _inside(t: float | np.ndarray, iv: np.ndarray) -> np.ndarray:
    """Whether times lie in any of the sorted, non-overlapping intervals ``iv``."""
    t = np.atleast_1d(np.asarray(t, dtype=np.float64))
    if len(iv) == 0:
        return np.zeros(len(t), bool)
    i = np.searchsorted(iv[:, 0], t, "right") - 1
    return (i >= 0) & (t < iv[np.maximum(i, 0), 1])


def _coverage(view: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Seconds in view before each of ``edges`` (the cumulative of the merged intervals)."""
    if len(view) == 0:
        return np.zeros(len(edges))
    lengths = view[:, 1] - view[:, 0]
    before = np.concatenate(([0.0], np.cumsum(lengths)[:-1]))
    xs = np.stack([view[:, 0], view[:, 1]], axis=1).ravel()
    ys = np.stack([before, before + lengths], axis=1).ravel()
    return np.interp(edges, xs, ys, left=0.0, right=ys[-1])


def simulate_household(rng: np.random.Generator, days: int, p: Params) -> Household:
    """One household's ``days`` days (module doc)."""
    wake_mu = rng.uniform(*p.wake_mean_h)
    bed_mu = rng.uniform(*p.bed_mean_h)
    sd = p.time_in_bed_sd_h / math.sqrt(2.0)          # split equally: var(bed) + var(wake) = 1.31 h squared
    rate = rng.uniform(*p.visits_per_h)
    tv_p = rng.uniform(*p.tv_evening_p)
    out_p = rng.uniform(*p.outing_p)
    day0 = BASE_UNIX + np.arange(days) * DAY_S
    wake = day0 + (wake_mu + sd * rng.standard_normal(days)) * HOUR_S
    bed = day0 + (bed_mu + sd * rng.standard_normal(days)) * HOUR_S
    bed = np.maximum(bed, wake + 10 * HOUR_S)          # at least 10 h up (a draw 6 SD apart otherwise)
    wake[1:] = np.maximum(wake[1:], bed[:-1] + 4 * HOUR_S)   # at least 4 h in bed
    sleep = np.stack([np.append(BASE_UNIX, bed), np.append(wake, day0[-1] + DAY_S)], axis=1)
    views, aways = [], []
    for k in range(days):
        w, b = wake[k], bed[k]
        n = rng.poisson(rate * (b - w) / HOUR_S)
        starts = rng.uniform(w, b, n)
        dwell = np.clip(rng.exponential(p.dwell_mean_min * 60.0, n), p.dwell_min_s, p.dwell_max_min * 60.0)
        iv = [np.stack([starts, starts + dwell], axis=1)]
        meals = [w + rng.uniform(0, 1800), day0[k] + rng.uniform(12.0, 13.5) * HOUR_S,
                 day0[k] + rng.uniform(18.0, 19.5) * HOUR_S]
        iv.append(np.array([[s, s + rng.uniform(*p.meal_min) * 60.0] for s in meals]))
        if rng.random() < tv_p:
            end = b - rng.uniform(0, 1800)
            iv.append(np.array([[end - rng.uniform(*p.tv_h) * HOUR_S, end]]))
        day_iv = np.clip(np.concatenate(iv), w, b)
        if rng.random() < out_p:
            dur = np.clip(p.outing_median_h * math.exp(p.outing_sigma * rng.standard_normal()), *p.outing_h) * HOUR_S
            lo, hi = w + HOUR_S, b - HOUR_S - dur
            if hi > lo:
                s = rng.uniform(lo, hi)
                aways.append((s, s + dur))
                # nothing in view while away: cut every interval at the outing
                before = day_iv.copy()
                before[:, 1] = np.minimum(before[:, 1], s)
                after = day_iv.copy()
                after[:, 0] = np.maximum(after[:, 0], s + dur)
                day_iv = np.concatenate([before, after])
        views.append(day_iv[day_iv[:, 1] > day_iv[:, 0]])
    view = _merge(np.concatenate(views))
    away = np.array(aways, dtype=np.float64).reshape(-1, 2)
    minute = BASE_UNIX + np.arange(days * 1440) * MINUTE_S
    cov = _coverage(view, np.append(minute, minute[-1] + MINUTE_S))
    person = np.clip(np.diff(cov), 0.0, MINUTE_S)
    info = {"wake_mean_h": round(wake_mu, 2), "bed_mean_h": round(bed_mu, 2), "visits_per_h": round(rate, 2),
            "tv_evening_p": round(tv_p, 2), "outing_p": round(out_p, 2)}
    return Household(minute, np.full(len(minute), MINUTE_S), person, view, _merge(sleep), away,
                     np.stack([wake, bed], axis=1), info)


def _chunk(h: Household, k: int, days: int, person: np.ndarray | None = None, stop: int | None = None) -> Minutes:
    """The minutes the usual of an absence starting on day ``k`` can use: from ``days`` + 1 days before day k (the
    window's reach included) to the end of day k + 1 (or to minute index ``stop``); ``person`` replaces the
    person seconds (a fall's copy)."""
    lo = max(0, (k - days - 1) * 1440)
    hi = min(len(h.minute), (k + 2) * 1440) if stop is None else stop
    ps = h.person_s if person is None else person
    return Minutes(h.minute[lo:hi], h.watched_s[lo:hi], ps[lo:hi])


def _state(h: Household, t: float) -> str:
    if _inside(t, h.sleep)[0]:
        return "night"
    if _inside(t, h.away)[0]:
        return "away"
    return "home"


def evaluate_household(h: Household, plan: Plan, rng: np.random.Generator, counters: dict) -> dict:
    """The false notices on the household's judged days and its falls' notice delays, per variant."""
    days = len(h.awake)
    first = plan.params.learn_only_days
    start, end = BASE_UNIX + first * DAY_S, BASE_UNIX + days * DAY_S
    saw = np.flatnonzero(h.person_s >= SEEN_S)
    t0s = h.minute[saw] + MINUTE_S
    backs = np.append(h.minute[saw[1:]], end)                   # the next SAW minute's start (end: censored)
    length = backs - t0s                                         # watched seconds: every minute watched
    pick = (t0s >= start) & (t0s < end) & (length > plan.margin_s)   # shorter than the margin: never a notice
    out = {name: {"false": {"night": 0, "away": 0, "home": 0}, "delays": []} for name, _ in VARIANTS}
    cache: dict[int, Minutes] = {}
    for t0, n in zip(t0s[pick], length[pick], strict=True):
        k = int((t0 - BASE_UNIX) // DAY_S)
        m = cache.get(k)
        if m is None:
            cache.clear()
            m = cache[k] = _chunk(h, k, plan.absence_days)
        for name, after in _afters(m, t0, plan, counters, length=n):
            if after is not None and n > after and t0 + after < end:
                out[name]["false"][_state(h, t0 + after)] += 1
    fall_days = rng.choice(np.arange(first, days), size=min(plan.params.falls_per_household, days - first),
                           replace=False)
    for k in np.sort(fall_days):
        t_f = _fall_time(h, int(k), rng)
        if t_f is None:
            counters["falls_skipped"] += 1
            continue
        i = int((t_f - BASE_UNIX) // MINUTE_S)                  # the minute of the fall
        person = h.person_s.copy()
        # the fall's copy: in view only before the fall (the minute of the fall up to it)
        cov = _coverage(h.view, np.array([h.minute[i], t_f]))
        person[i] = min(cov[1] - cov[0], MINUTE_S)
        m = _chunk(h, int(k), plan.absence_days, person, stop=i + 1)
        t0 = last_seen(m)
        if t0 is None:
            counters["falls_skipped"] += 1
            continue
        for name, after in _afters(m, t0, plan, counters):
            delay = math.inf if after is None else max(t0 + after - t_f, 0.0)
            out[name]["delays"].append(delay if delay <= FOUND_AFTER_S else math.inf)
    return out


def _afters(m: Minutes, t0: float, plan: Plan, counters: dict, length: float | None = None):
    """(variant, watched seconds after which the notice is due; None while learning) for an absence from ``t0``.
    The usual never shrinks as the window grows (more candidates, each with the same value), so once a narrower
    window gives no notice for an absence of ``length`` watched seconds, the wider ones are not computed (None:
    no notice either)."""
    results = {}
    for name, window in sorted(VARIANTS, key=lambda v: v[1]):
        u = usual_absence(m, t0, plan.absence_days, plan.learn_days, tz=None, window_s=window)
        counters["usual_absence_calls"] += 1
        after = results[name] = u.notice_after_s(plan.margin_s)
        if length is not None and (after is None or after >= length):
            break
    return [(name, results.get(name)) for name, _ in VARIANTS]


def _fall_time(h: Household, k: int, rng: np.random.Generator) -> float | None:
    """A random awake time of day ``k`` at home, out of view; None when 200 draws found none."""
    w, b = h.awake[k]
    for _ in range(200):
        t = float(rng.uniform(w, b))
        if not (_inside(t, h.away)[0] or _inside(t, h.view)[0]):
            return t
    return None


def _quantile(x: np.ndarray, q: float) -> float:
    return float(np.quantile(x, q, method="inverted_cdf")) if len(x) else math.nan


def run_bench(plan: Plan, progress=lambda msg: None) -> dict:
    """The benchmark's report (``posed bench absence --json``)."""
    t_start = time.monotonic()
    rng = np.random.default_rng(plan.seed)
    counters = {"usual_absence_calls": 0, "falls_skipped": 0}
    agg = {name: {"false": {"night": 0, "away": 0, "home": 0}, "delays": []} for name, _ in VARIANTS}
    sim = {"visits_in_view_per_awake_h": [], "out_of_home_h_per_day": [], "absences_over_margin_per_day": []}
    judged_days = plan.households * max(plan.days - plan.params.learn_only_days, 0)
    for n in range(plan.households):
        h = simulate_household(rng, plan.days, plan.params)
        res = evaluate_household(h, plan, rng, counters)
        for name in agg:
            for s, c in res[name]["false"].items():
                agg[name]["false"][s] += c
            agg[name]["delays"] += res[name]["delays"]
        awake_h = float(np.sum(h.awake[:, 1] - h.awake[:, 0])) / HOUR_S
        sim["visits_in_view_per_awake_h"].append(len(h.view) / awake_h)
        sim["out_of_home_h_per_day"].append(float(np.sum(h.away[:, 1] - h.away[:, 0])) / HOUR_S / plan.days)
        if (n + 1) % 50 == 0:
            progress(f"{n + 1}/{plan.households} households, {time.monotonic() - t_start:.1f} s")
    month = judged_days / MONTH_DAYS if judged_days else math.nan
    variants = []
    for name, window in VARIANTS:
        f = agg[name]["false"]
        d = np.array(agg[name]["delays"], dtype=np.float64)
        total = sum(f.values())
        variants.append({
            "variant": name, "window_s": window,
            "false_notices": total,
            "false_per_household_month": _r(total / month if judged_days else math.nan, 3),
            "false_per_household_month_by_state": {s: _r(c / month if judged_days else math.nan, 3)
                                                   for s, c in f.items()},
            "falls": int(len(d)),
            "noticed_within_h": {str(x): _r(float(np.mean(d <= x * HOUR_S)) if len(d) else math.nan, 3)
                                 for x in WITHIN_H},
            "median_delay_h": _r(_quantile(d, 0.5) / HOUR_S, 2),
            "p90_delay_h": _r(_quantile(d, 0.9) / HOUR_S, 2),
            "not_noticed_within_24h": _r(float(np.mean(np.isinf(d))) if len(d) else math.nan, 3),
        })
    return {
        "benchmark": "absence",
        "model": "SIMULATED households (bench/absence.py, docs/bench/absence.md): a model of routines, not a "
                 "measurement of real ones; the rule's constants were set before this benchmark and not tuned on it",
        "plan": {"seed": plan.seed, "households": plan.households, "days": plan.days,
                 "judged_days_per_household": max(plan.days - plan.params.learn_only_days, 0),
                 "rule": {"margin_s": plan.margin_s, "absence_days": plan.absence_days, "learn_days": plan.learn_days,
                          "seen_s": SEEN_S, "tz": None, "found_after_fall_s": FOUND_AFTER_S},
                 "simulation": asdict(plan.params)},
        "simulated": {k: _r(float(np.mean(v)), 2) for k, v in sim.items() if v},
        "variants": variants,
        "usual_absence_calls": counters["usual_absence_calls"],
        "falls_skipped": counters["falls_skipped"],
        "elapsed_s": round(time.monotonic() - t_start, 1),
        "machine": machine(),
    }


def _r(x: float, digits: int) -> float | None:
    """Rounded; None for NaN or infinity (JSON has neither)."""
    return None if x is None or not math.isfinite(x) else round(float(x), digits)


def table(report: dict) -> list[str]:
    """The report as text lines (``posed bench absence``)."""
    p = report["plan"]
    m = report["machine"]
    s = report.get("simulated", {})
    lines = [f"SIMULATED households (a model, not a measurement): {p['households']} households x {p['days']} days "
             f"(first {p['days'] - p['judged_days_per_household']} only learned), seed {p['seed']}; "
             f"{report['variants'][0]['falls']} falls out of view",
             f"simulated: {s.get('visits_in_view_per_awake_h')} times in view per awake hour, "
             f"{s.get('out_of_home_h_per_day')} h a day out of home; margin {p['rule']['margin_s'] / 3600:g} h",
             "",
             f"{'variant':<24} {'false/month':>11} {'night':>6} {'away':>6} {'home':>6} "
             + " ".join(f"{'<=' + str(x) + ' h':>7}" for x in WITHIN_H)
             + f" {'median h':>8} {'p90 h':>6} {'>24 h':>6}"]
    for v in report["variants"]:
        by = v["false_per_household_month_by_state"]
        within = " ".join(f"{_pct(v['noticed_within_h'][str(x)]):>7}" for x in WITHIN_H)
        lines.append(f"{v['variant']:<24} {_f(v['false_per_household_month'], 3):>11} {_f(by['night'], 3):>6} "
                     f"{_f(by['away'], 3):>6} {_f(by['home'], 3):>6} {within} {_f(v['median_delay_h'], 2):>8} "
                     f"{_f(v['p90_delay_h'], 2):>6} {_pct(v['not_noticed_within_24h']):>6}")
    lines += ["",
              "false/month: notices per household-month when nothing happened (night: while asleep; away: while out "
              "of home; home: awake at home); <=N h: share of falls noticed within N h of the fall",
              f"machine: {m['cpu']}, {m['cores']} cores, load {m['load_avg_1m']}; {report['elapsed_s']} s, "
              f"{report['usual_absence_calls']} usual_absence calls"]
    return lines


def _f(x, digits: int) -> str:
    return "-" if x is None else f"{x:.{digits}f}"


def _pct(x) -> str:
    return "-" if x is None else f"{100 * x:.1f} %"
