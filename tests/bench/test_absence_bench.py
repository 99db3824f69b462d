"""bench.absence (``posed bench absence``): the "not seen for longer than usual" notice on simulated households.

Small runs (a few households, 30 days): the simulated minutes table is what the history would hold; the window
never adds false notices (window off gives at least as many as 1.5 h on the same households); a fall out of view
is noticed, after it; the JSON has its keys; a seed gives the same numbers twice.
"""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np

from posed.bench import absence
from posed.cli import main
from posed.falls.absence import Minutes


def small(households: int = 4, days: int = 30, seed: int = 3, **params) -> absence.Plan:
    return absence.Plan(households=households, days=days, seed=seed,
                        params=replace(absence.Params(), **params))


def by_name(report: dict) -> dict:
    return {v["variant"]: v for v in report["variants"]}


def test_minutes_table_is_well_formed():
    h = absence.simulate_household(np.random.default_rng(1), 30, absence.Params())
    assert len(h.minute) == 30 * 1440
    assert np.all(np.diff(h.minute) == 60.0) and h.minute[0] == absence.BASE_UNIX
    assert np.all(h.watched_s == 60.0)
    assert np.all((h.person_s >= 0.0) & (h.person_s <= 60.0))
    assert 0 < np.count_nonzero(h.person_s >= 2.0) < len(h.minute) / 2   # seen, but not all day
    Minutes(h.minute, h.watched_s, h.person_s)                              # what the rule accepts
    # asleep means out of view: no person seconds in a minute wholly inside a night
    nights = absence._inside(h.minute + 30.0, h.sleep) & absence._inside(h.minute, h.sleep) \
        & absence._inside(h.minute + 59.9, h.sleep)
    assert nights.any() and np.all(h.person_s[nights] == 0.0)


def test_window_off_gives_at_least_as_many_false_notices():
    report = absence.run_bench(small(falls_per_household=0))
    v = by_name(report)
    default, off = v["window 1.5 h (default)"], v["window off (0)"]
    assert default["falls"] == 0 and off["falls"] == 0
    assert off["false_notices"] >= default["false_notices"]
    assert off["false_notices"] > 0          # the model's early nights and late walks do give notices without it
    assert v["window 2 h"]["false_notices"] <= default["false_notices"]


def test_fall_out_of_view_is_noticed_after_it():
    report = absence.run_bench(small(households=3, falls_per_household=3))
    default = by_name(report)["window 1.5 h (default)"]
    assert default["falls"] == 9
    assert default["noticed_within_h"]["12"] > 0
    assert default["median_delay_h"] is not None and default["median_delay_h"] > 0
    assert default["p90_delay_h"] >= default["median_delay_h"]
    within = [default["noticed_within_h"][str(x)] for x in absence.WITHIN_H]
    assert within == sorted(within)


def test_json_has_the_keys(capsys):
    code = main(["bench", "absence", "--json", "--households", "2", "--days", "20", "--seed", "5"])
    report = json.loads(capsys.readouterr().out)
    assert code == 0
    assert report["benchmark"] == "absence" and "posed_version" in report
    assert {"seed", "households", "days", "rule", "simulation"} <= set(report["plan"])
    assert report["plan"]["seed"] == 5 and report["plan"]["households"] == 2 and report["plan"]["days"] == 20
    assert {"cpu", "cores", "python"} <= set(report["machine"])
    assert [v["window_s"] for v in report["variants"]] == [5400.0, 0.0, 7200.0]
    for v in report["variants"]:
        assert {"false_per_household_month", "false_per_household_month_by_state", "noticed_within_h",
                "median_delay_h", "p90_delay_h", "not_noticed_within_24h", "falls"} <= set(v)


def test_fixed_seed_gives_identical_output(capsys):
    def numbers(text: str) -> dict:
        r = json.loads(text)
        return {k: r[k] for k in ("plan", "simulated", "variants", "usual_absence_calls")}

    args = ["bench", "absence", "--json", "--households", "3", "--days", "25", "--seed", "11"]
    assert main(args) == 0
    first = numbers(capsys.readouterr().out)
    assert main(args) == 0
    assert numbers(capsys.readouterr().out) == first
    assert main(args[:-1] + ["12"]) == 0
    assert numbers(capsys.readouterr().out) != first


def test_false_notices_match_every_absence_judged_on_the_whole_table():
    """The bench's shortcuts (absences under the margin skipped, the usual read from a slice of the days, wider
    windows skipped once a narrower one gives no notice) change nothing: judged plainly, absence by absence, on
    the whole table with the real rule, the same notices."""
    from posed.falls.absence import SEEN_S, usual_absence

    plan = small(days=24, falls_per_household=0)
    h = absence.simulate_household(np.random.default_rng(7), plan.days, plan.params)
    counters = {"usual_absence_calls": 0, "falls_skipped": 0}
    got = absence.evaluate_household(h, plan, np.random.default_rng(0), counters)
    m = Minutes(h.minute, h.watched_s, h.person_s)
    saw = np.flatnonzero(h.person_s >= SEEN_S)
    end = absence.BASE_UNIX + plan.days * 86400.0
    start = absence.BASE_UNIX + plan.params.learn_only_days * 86400.0
    for name, window in absence.VARIANTS:
        plain = 0
        for a, b in zip(saw[:-1], saw[1:], strict=True):
            t0 = h.minute[a] + 60.0
            if b == a + 1 or not start <= t0 < end:
                continue
            after = usual_absence(m, t0, plan.absence_days, plan.learn_days, window_s=window).notice_after_s(3600.0)
            plain += after is not None and h.minute[b] - t0 > after and t0 + after < end
        assert sum(got[name]["false"].values()) == plain, name
