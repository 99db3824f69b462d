"""The daily summary for a caregiver: one self-contained HTML file (tables, and PNG pictures inlined as
base64: it opens offline, can be mailed, and loads nothing from anywhere).

What it holds: whether posed was watching (the minutes it received frames, ``watched``: none means off or
no camera), time spent standing, sitting, lying, in view without a measured posture, and with nobody in view
(``viz.posture``, whose rules and limits are printed in the report), never counting the rest of a day not
over; sit-to-stand transitions, walking bouts, the falls and how each ended (got up, alarm, still on the
floor, in progress when the report was made, or no further message) said against the time posed watched; the
day's joint-angle ranges; the day hour by hour (one bar per hour, a cell per minute); the angle plot. Where
posed watched nothing, nothing is counted: "not measured", never 0.

The pauses for privacy (a person asked posed to stop watching for a while: the history's ``paused`` table,
``daemon.history.paused``) are listed and summed, and counted apart: a minute paused is neither watched nor
"not watching" (off, or no camera). A day without a pause reads as it did before pausing existed.

A fall's states are said in the words of every other view (``viz.series.STATE_WORDS``: fall, on the floor,
ALARM, got up), as the web page says them.
"""

from __future__ import annotations

import base64
import datetime as dt
import html
import io
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from posed.falls import FallsConfig
from posed.viz import posture
from posed.viz.names import MEASURED_ANGLES, PANELS, short_label
from posed.viz.plots import FALL_COLOUR, clock, plot_angles, zone_text
from posed.viz.series import CLOCK_SLACK_S, AngleSeries, Episode, states_text

BODY_ANGLES = ("theta_bd", "phi_bd", "psi_bd")
# a fall whose last message (fall, on the floor) is this recent when the report is made is still going on: the
# detector raises the alarm alarm_after_s after the impact unless the person gets up (docs/falls.md), so
# until then (and a margin for the message's way to the journal) "no further message" means "not yet"
IN_PROGRESS_MARGIN_S = 10.0
NOT_MEASURED = "not measured"


def _png_tag(png: bytes, alt: str) -> str:
    return (f'<img alt="{html.escape(alt)}" style="max-width:100%" '
            f'src="data:image/png;base64,{base64.b64encode(png).decode()}">')


def _hm(seconds: float) -> str:
    m = int(round(seconds / 60.0))
    return f"{m // 60} h {m % 60:02d} min" if m >= 60 else (f"{m} min" if m else f"{seconds:.0f} s")


# what a minute of the day was: the posture seen most in it, else why there is none
POSTURE_STYLE = {"standing": ("#4c9f70", ""), "sitting": ("#e0a030", "//"), "lying": ("#c0392b", "xx")}
OTHER_STYLE = {"in view, posture not measured": ("#9fb7d0", ".."),
               "watching, nobody in view": ("#dedede", ""),
               "paused for privacy": ("#cdc6ea", "\\\\"),
               "not watching (posed off or no camera)": ("#ffffff", "---"),
               "not seen (posed's history does not say whether it watched)": ("#ffffff", ""),
               "not yet": ("#f4f4f4", "")}
MINUTE_STYLE = {**POSTURE_STYLE, **OTHER_STYLE}
IN_VIEW, NOBODY, PAUSED, OFF, UNKNOWN, NOT_YET = OTHER_STYLE


@dataclass(frozen=True)
class DayPause:
    """One pause for privacy as the day's report counts it, unix seconds: ``start``..``end`` the part of it in
    the day and before the report was made; ``since_unix``, ``end_unix`` (when it stopped: ended, else the
    earlier of ``until_unix`` and now) and ``until_unix`` (when it was due to end) the whole pause; ``by`` who
    asked, ``ended`` how it ended (``time``, ``resumed``, ``stopped``; None: not recorded — still paused when
    the report was made, or posed killed during it), ``resumed_by`` who asked to resume."""

    start: float
    end: float
    since_unix: float
    end_unix: float
    until_unix: float
    by: str | None
    ended: str | None
    resumed_by: str | None


def day_pauses(paused: Sequence, span: tuple[float, float], now: float) -> list[DayPause]:
    """The day's part of each pause (``PauseLog.between`` rows: objects with ``since_unix``, ``until_unix``,
    ``ended_unix``, ``by``, ``ended``, ``resumed_by``; unix seconds) up to ``now``, in time order; pauses
    wholly outside it left out."""
    out = []
    for p in paused:
        since = float(p.since_unix)
        stop = max(since, float(p.ended_unix) if p.ended_unix is not None else min(float(p.until_unix), now))
        start, end = max(since, span[0]), min(stop, span[1], now)
        if end > start:
            out.append(DayPause(start, end, since, stop, float(p.until_unix), p.by, p.ended, p.resumed_by))
    return sorted(out, key=lambda d: (d.start, d.end))


def _covered(pieces: Sequence[tuple[float, float]]) -> float:
    """Seconds covered by the (start, end) pieces, overlaps counted once."""
    total, reach = 0.0, -np.inf
    for a, b in sorted(pieces):
        if b > reach:
            total += b - max(a, reach)
            reach = b
    return total


@dataclass(frozen=True)
class DayTime:
    """Where a day's time went, seconds, the future never counted: ``elapsed`` (midnight to now, or the
    whole day), ``postures`` (standing, sitting, lying: from the angle history), ``watching`` (posed received
    frames), ``person`` (of them with a person in view), ``future`` (the rest of today); ``known`` False when
    the history has no record of when posed watched (then ``watching`` and ``person`` are None); ``paused``
    (paused for privacy: neither watching nor "not watching")."""

    elapsed: float
    postures: dict[str, float]
    watching: float | None
    person: float | None
    future: float
    paused: float = 0.0

    @property
    def known(self) -> bool:
        return self.watching is not None

    def rows(self) -> list[tuple[str, float]]:
        """(what, seconds) rows of the report's table, in reading order; together they make ``elapsed``."""
        seen = sum(self.postures.values())
        out = [(p, self.postures[p]) for p in posture.POSTURES]
        paused = [(PAUSED, self.paused)] if self.paused > 0 else []
        if self.known:
            out += [(IN_VIEW, max(0.0, self.person - seen)), (NOBODY, max(0.0, self.watching - max(self.person, seen))),
                    *paused, (OFF, self.off)]
        else:
            out += [*paused, (UNKNOWN, max(0.0, self.elapsed - seen - self.paused))]
        return out

    @property
    def off(self) -> float | None:
        """Seconds posed was not watching (off, or no camera) and not paused; None when not known."""
        if not self.known:
            return None
        return max(0.0, self.elapsed - max(self.watching, sum(self.postures.values())) - self.paused)


def day_time(summary: posture.DaySummary, watched: Sequence[tuple] | None, span: tuple[float, float],
             now: float, paused: Sequence[DayPause] = ()) -> DayTime:
    """The day's accounting from the posture summary, the watched minutes (``WatchLog.minutes`` rows:
    minute, frames, person, fitted, watched_s, person_s; None: not recorded) and the day's pauses for privacy
    (``day_pauses``) up to ``now``."""
    until = min(span[1], now)
    elapsed = max(0.0, until - span[0])
    postures = {p: summary.seconds[p] for p in posture.POSTURES}
    held = min(elapsed, _covered([(p.start, p.end) for p in paused]))
    if watched is None:
        return DayTime(elapsed, postures, None, None, span[1] - span[0] - elapsed, held)
    rows = [r for r in watched if span[0] <= r[0] < until]
    watching = min(elapsed, float(sum(r[4] for r in rows)))
    person = min(watching, float(sum(r[5] for r in rows)))
    return DayTime(elapsed, postures, watching, person, span[1] - span[0] - elapsed, held)


def minute_states(summary: posture.DaySummary, watched: Sequence[tuple] | None, span: tuple[float, float],
                  now: float, paused: Sequence[DayPause] = ()) -> list[str]:
    """One state per minute of the day (``MINUTE_STYLE``'s keys): the posture seen longest in it, else paused
    for privacy (when the pause took at least as much of the minute as posed watched of it), in view with no
    posture measured, nobody in view, not watching, not seen (unknown), or not yet."""
    n = int(round((span[1] - span[0]) / 60.0))
    seconds = [dict.fromkeys(posture.POSTURES, 0.0) for _ in range(n)]
    held = [0.0] * n                        # seconds of each minute paused for privacy
    for p in paused:
        for i in range(max(0, int((p.start - span[0]) // 60)), min(n, int(np.ceil((p.end - span[0]) / 60)))):
            held[i] += max(0.0, min(p.end, span[0] + 60.0 * (i + 1)) - max(p.start, span[0] + 60.0 * i))
    for r in summary.runs:
        t = r.start
        while t < r.end:
            i = int((t - span[0]) // 60)
            edge = min(r.end, span[0] + 60.0 * (i + 1))
            if 0 <= i < n:
                seconds[i][r.posture] += edge - t
            t = edge
    rows = {} if watched is None else {int(r[0]): r for r in watched}
    out = []
    for i in range(n):
        t = span[0] + 60.0 * i
        best = max(posture.POSTURES, key=lambda p, s=seconds[i]: s[p])
        row = rows.get(int(t))
        if seconds[i][best] > 0:
            out.append(best)
        elif t >= now:
            out.append(NOT_YET)
        elif held[i] > 0 and held[i] >= (row[4] if row is not None else 0.0):
            out.append(PAUSED)
        elif watched is None:
            out.append(UNKNOWN)
        elif row is None or row[4] <= 0:
            out.append(OFF)
        else:
            out.append(IN_VIEW if row[5] > 0 else NOBODY)
    return out


def day_grid_figure(states: Sequence[str], falls: Sequence[Episode], span: tuple[float, float], tz: dt.tzinfo,
                    width_px: int = 1200, dpi: int = 110) -> Figure:
    """The day hour by hour: one bar per hour, one cell per minute in the colour (and hatch, for grey print)
    of what that minute was (``minute_states``); a fall's minute outlined in red, its number at the end of its
    hour's bar (one text per hour, so numbers never overlap)."""
    from matplotlib.patches import Rectangle

    hours = (len(states) + 59) // 60
    height_in = 0.24 * hours + 1.6
    fig = Figure(figsize=(width_px / dpi, height_in), dpi=dpi)
    FigureCanvasAgg(fig)
    ax = fig.add_axes((0.075, 1.05 / height_in, 0.79, 1 - 1.25 / height_in))
    for h in range(hours):
        m = 0
        cells = states[60 * h: 60 * h + 60]
        while m < len(cells):
            e = m
            while e < len(cells) and cells[e] == cells[m]:
                e += 1
            colour, hatch = MINUTE_STYLE[cells[m]]
            ax.add_patch(Rectangle((m, h + 0.1), e - m, 0.8, facecolor=colour, hatch=hatch, edgecolor="#888888",
                                   linewidth=0.0))
            m = e
        ax.add_patch(Rectangle((0, h + 0.1), len(cells), 0.8, fill=False, edgecolor="#bbbbbb", linewidth=0.5))
    per_hour: dict[int, list[int]] = {}
    for i, ep in enumerate(falls, 1):
        k = int((ep.start - span[0]) // 60)
        if 0 <= k < len(states):
            per_hour.setdefault(k // 60, []).append(i)
            ax.add_patch(Rectangle((k % 60 - 0.3, k // 60 + 0.02), 1.6, 0.96, fill=False, edgecolor=FALL_COLOUR,
                                   linewidth=1.6))
    for h, numbers in per_hour.items():
        text = (f"fall {numbers[0]}" if len(numbers) == 1 else "falls " + ", ".join(map(str, numbers))
                if len(numbers) <= 4 else f"falls {numbers[0]}-{numbers[-1]}")
        ax.text(61, h + 0.5, text, color=FALL_COLOUR, va="center", ha="left", fontsize=8.5)
    ax.set_xlim(0, 60)
    ax.set_ylim(hours, 0)
    # the hour the clocks go back is there twice (01:00 BST, 01:00 GMT); the hour they skip is not there
    labels = [clock(span[0] + 3600 * h, tz, "%H:%M", short=True) for h in range(hours)]
    ax.set_yticks([h + 0.5 for h in range(hours)], labels, fontsize=8)
    ax.set_xticks([0, 10, 20, 30, 40, 50, 60], [":00", ":10", ":20", ":30", ":40", ":50", ":60"], fontsize=8)
    ax.tick_params(length=0)
    for side in ("top", "right", "left", "bottom"):
        ax.spines[side].set_visible(False)
    ax.set_xlabel(f"minute of the hour; clock time of the robot ({zone_text(tz, span[0], span[1])}); a fall's "
                  "minute is outlined in red", fontsize=9)
    handles = [Patch(facecolor=c, hatch=h, edgecolor="#888888", label=k) for k, (c, h) in MINUTE_STYLE.items()
               if k in set(states)]
    fig.legend(handles=handles, loc="lower center", ncol=min(4, len(handles)), frameon=False, fontsize=8.5,
               bbox_to_anchor=(0.5, 0.0))
    return fig


def day_grid_png(states: Sequence[str], falls: Sequence[Episode], span: tuple[float, float], tz: dt.tzinfo) -> bytes:
    buf = io.BytesIO()
    day_grid_figure(states, falls, span, tz).savefig(buf, format="png")
    return buf.getvalue()


def angle_ranges(series: AngleSeries) -> list[tuple[str, int, float, float, float, float, float]]:
    """(plain name, samples, min, 5th percentile, median, 95th percentile, max) per measured angle."""
    out = []
    for name in MEASURED_ANGLES:
        if name in BODY_ANGLES:   # the body's orientation to the camera says nothing about the person
            continue
        v = series.angles.get(name)
        if v is None:
            continue
        v = v[np.isfinite(v)]
        if not len(v):
            continue
        p5, p50, p95 = np.percentile(v, [5, 50, 95])
        out.append((short_label(name), len(v), float(v.min()), float(p5), float(p50), float(p95),
                    float(v.max())))
    return out


def day_report(series: AngleSeries, falls: Sequence[Episode], day: dt.date, tz: dt.tzinfo, *, robot: str,
               sources: str, max_step_s: float = 1.0, watched: Sequence[tuple] | None = None,
               now: float | None = None, down=None, in_progress_s: float | None = None,
               stamped_later: int = 0, paused: Sequence = ()) -> str:
    """The HTML text of the day's report. ``series`` on the robot's clock (unix seconds), ``falls`` the
    day's episodes (journal), ``sources`` a line naming the files it was made from, ``watched`` the minutes
    posed watched (``WatchLog.minutes`` rows; None: this history does not record them), ``now`` the time
    the report is made (unix; default now): nothing after it is counted; ``down``: the camera's down the
    postures are measured against (camera axes; None: the camera taken as level; viz.posture);
    ``in_progress_s``: a fall whose last message is younger than this when the report is made is "in
    progress" (default: the fall detector's default ``alarm_after_s`` plus ``IN_PROGRESS_MARGIN_S``);
    ``stamped_later``: fall events of the journal outside this day stamped later than ``now`` (a clock that was
    wrong), said so that a fall hidden on a day still to come is not missed; ``paused``: the pauses for privacy
    that overlap the day (``PauseLog.between`` rows), listed, summed and counted apart from "not watching".

    Samples stamped later than ``now`` are not counted (the robot's clock was wrong when they were stored, or
    is wrong now), and said; falls so stamped are listed, never "in progress"."""
    import time

    now = time.time() if now is None else now
    if in_progress_s is None:
        in_progress_s = FallsConfig().alarm_after_s + IN_PROGRESS_MARGIN_S
    start = dt.datetime.combine(day, dt.time(0), tz).timestamp()
    end = dt.datetime.combine(day + dt.timedelta(days=1), dt.time(0), tz).timestamp()
    span = (start, end)     # 23 or 25 hours the day the clocks go forward or back: every duration is unix time
    later = int(np.count_nonzero(series.time > now + CLOCK_SLACK_S))
    if later:               # stamped after now: a clock wrong then or now; never counted as time that has passed
        keep = series.time <= now + CLOCK_SLACK_S
        series = AngleSeries(series.time[keep], {k: v[keep] for k, v in series.angles.items()}, series.clock)
    summary = posture.summarise(series.time, series.angles, span, max_step_s, down)
    pauses = day_pauses(paused, span, now)
    acct = day_time(summary, watched, span, now, pauses)

    def fmt(t: float) -> str:
        return clock(t, tz)

    esc = html.escape
    so_far = "the whole day" if acct.future <= 0 else (
        "the day so far: " + ("it has not begun" if acct.elapsed <= 0 else f"up to {fmt(now)}"))
    parts = [f"<!doctype html><html lang='en'><head><meta charset='utf-8'><title>posed: {esc(robot)}, "
             f"{day.isoformat()}</title><style>{_CSS}</style></head><body>",
             f"<h1>Daily summary, {day.strftime('%A %d %B %Y')}</h1>",
             f"<p class='meta'>Robot <b>{esc(robot)}</b>; clock: the robot's local time "
             f"({esc(zone_text(tz, start, end))}){_day_length(start, end)}."
             f" Covers {esc(so_far)}. Made from {esc(sources)}.</p>"]
    parts.append(_watching_html(acct, falls))
    parts.append(_paused_html(pauses, acct.paused, day, tz, now))
    parts.append(_stamped_later_html(later, [ep for ep in falls if ep.end > now + CLOCK_SLACK_S], stamped_later,
                                     fmt(now)))
    share_head = "share of the day so far" if acct.future > 0 else "share of the day"
    parts.append(f"<h2>The day</h2><table><tr><th></th><th>time</th><th>{share_head}</th></tr>")
    for what, secs in acct.rows():
        share = "" if acct.elapsed <= 0 else "0 %" if secs <= 0 else (
            "&lt;1 %" if secs < 0.005 * acct.elapsed else f"{100 * secs / acct.elapsed:.0f} %")
        cls = " class='warn'" if what == OFF and secs > 0 else ""
        parts.append(f"<tr><td{cls}>{esc(what)}</td><td>{_hm(secs)}</td><td>{share}</td></tr>")
    if acct.future > 0:
        parts.append(f"<tr><td class='small'>{esc(NOT_YET)} (the day is not over)</td><td class='small'>"
                     f"{_hm(acct.future)}</td><td></td></tr>")
    parts.append("</table>")
    parts.append(_png_tag(day_grid_png(minute_states(summary, watched, span, now, pauses), falls, span, tz),
                          "the day hour by hour: posture, in view, watching, not watching"))
    walk_s = sum(b.seconds for b in summary.walking_bouts)
    measured = sum(summary.seconds[p] for p in posture.POSTURES) > 0     # a posture was seen at all
    if measured:
        stands, walks = str(summary.sit_to_stand), f"{len(summary.walking_bouts)} ({_hm(walk_s)} in all)"
    else:   # nothing watched (or nobody seen): a count of 0 would read as "did not get up or walk"
        why = ("posed was not watching" if acct.known and acct.watching <= 0 else "no posture was measured")
        why += " (paused for privacy for a while)" if acct.paused > 0 and acct.known and acct.watching <= 0 else ""
        stands = walks = f"<span class='small'>{NOT_MEASURED} ({why})</span>"
    parts.append("<h2>Activity</h2><table>"
                 f"<tr><td>sit-to-stand transitions</td><td>{stands}</td></tr>"
                 f"<tr><td>walking bouts</td><td>{walks}</td></tr>"
                 "</table>")
    if summary.walking_bouts:
        parts.append("<p class='small'>Walking bouts: " + ", ".join(
            f"{fmt(b.start)} ({b.seconds:.0f} s)" for b in summary.walking_bouts[:30]) + "</p>")
    parts.append("<h2>Falls</h2>")
    if falls:
        parts.append("<table><tr><th></th><th>started</th><th>what happened</th><th>how it ended</th>"
                     "<th>acknowledged</th></tr>")
        for i, ep in enumerate(falls, 1):
            what = esc(states_text(ep.states))
            by = f" by {esc(', '.join(ep.acked_by))}" if ep.acked_by else ""
            if ep.acked is not None:
                ack = fmt(ep.acked) + by
            elif ep.unacked and len(ep.unacked) < len(ep.states):
                ack = (f"<b class='warn'>{esc(states_text(ep.unacked))}: no</b><br><span class='small'>"
                       f"{esc(states_text([s for s in ep.states if s not in ep.unacked]))}: yes{by}</span>")
            else:
                ack = "<b class='warn'>no</b>"
            whose = f" ({esc(ep.who)})" if ep.who else ""
            ended = esc(ep.outcome(now, in_progress_s, fmt))
            if ep.caveats(fmt):
                ended += "".join(f"<br><span class='small'>{esc(c)}</span>" for c in ep.caveats(fmt))
            parts.append(f"<tr><td>fall {i}{whose}</td><td>{fmt(ep.start)}</td><td class='states'>{what}</td>"
                         f"<td>{ended}</td><td>{ack}</td></tr>")
        parts.append("</table>")
    parts.append(f"<p>{_falls_sentence(acct, len(falls))}</p>")
    parts.append("<h2>Joint-angle ranges</h2><p class='small'>Degrees over the day's samples in which the camera "
                 "saw the joint (flexion positive; angles the model does not measure, and a joint in a frame "
                 "where its landmarks were not seen, are left out).</p>"
                 "<table><tr><th>angle</th><th>samples</th><th>min</th><th>5 %</th><th>median</th>"
                 "<th>95 %</th><th>max</th></tr>")
    ranges = angle_ranges(series)
    for name, n, *vals in ranges:
        parts.append(f"<tr><td>{esc(name)}</td><td>{n}</td>" + "".join(f"<td>{v:.0f}</td>" for v in vals)
                     + "</tr>")
    if not ranges:
        parts.append("<tr><td colspan='7' class='small'>no samples: the camera saw no joint this day"
                     + (" (posed was not watching)" if acct.known and acct.watching <= 0 else "") + "</td></tr>")
    parts.append("</table>")
    if len(series.time):
        png = plot_angles(series, [(k, PANELS[k]) for k in ("legs", "trunk")], falls, tz=tz,
                          title="Hips, knees and trunk over the day")
        parts.append("<h2>Joint angles</h2>" + _png_tag(png, "joint angles over the day"))
    parts.append("<h2>How this is worked out</h2><div class='small'>" + _method_html(down, bool(pauses)) + "</div>")
    parts.append("</body></html>")
    return "\n".join(parts)


def _day_length(start: float, end: float) -> str:
    """``; this day has 25 hours`` the day the clocks go back (23 the day they go forward), else nothing."""
    hours = (end - start) / 3600.0
    return "" if abs(hours - 24.0) < 1e-6 else f"; this day has {hours:g} hours"


def _stamped_later_html(samples: int, falls: Sequence[Episode], elsewhere: int, now_text: str) -> str:
    """What was stamped later than the report was made (a clock wrong then or now), said rather than counted."""
    if not (samples or falls or elsewhere):
        return ""
    what = [f"{samples} sample(s) of this day (not counted below)"] if samples else []
    if falls:
        what.append(f"{len(falls)} of this day's fall event(s) (listed below)")
    if elsewhere:
        what.append(f"{elsewhere} fall event(s) of a later day (<code>posed events</code> lists them)")
    return (f"<p class='notice warn'><b>Times later than now:</b> {html.escape(', '.join(what))} were stamped "
            f"later than this report was made ({html.escape(now_text)}). The robot's clock was wrong when they "
            "were recorded (set right since, e.g. by NTP at boot on a robot without a clock battery) or is wrong "
            "now: check it (<code>timedatectl</code>). When they really happened is unknown.</p>")


def _watching_html(acct: DayTime, falls: Sequence[Episode]) -> str:
    """The first thing a reader needs: whether posed was watching at all."""
    if not acct.known:
        return ("<p class='notice'>This history does not record when posed was watching (it was written by an "
                "older posed): 'not seen' below means nobody was seen <i>or</i> posed was not running.</p>")
    if acct.elapsed <= 0:
        return "<p class='notice'>This day has not begun.</p>"
    if acct.watching <= 0:
        why = "(off, or no camera)" if acct.paused <= 0 else (
            f"(paused for privacy for {_hm(acct.paused)}" + (", off or no camera the rest" if acct.elapsed - acct.paused >= 60
                                                              else "") + ")")
        return (f"<p class='notice warn'><b>posed was not watching at all this day</b> {why}: "
                "nothing below says anything about this person.</p>")
    off = acct.elapsed - acct.watching - acct.paused
    text = f"posed was watching for <b>{_hm(acct.watching)}</b> of {_hm(acct.elapsed)}"
    if acct.paused > 0:
        text += f"; paused for privacy for <b>{_hm(acct.paused)}</b> (below)"
    if off >= 60:
        text += f"; <b class='warn'>not watching for {_hm(off)}</b> (off, or no camera)"
    return f"<p class='notice'>{text}.</p>"


def _paused_html(pauses: Sequence[DayPause], total: float, day: dt.date, tz: dt.tzinfo, now: float) -> str:
    """The day's pauses for privacy, summed and listed: ``Watching paused for privacy: 45 min — 14:02–14:47,
    asked by voice, resumed by time`` (nothing on a day without one)."""
    if not pauses:
        return ""

    def at(t: float) -> str:
        text = clock(t, tz, "%H:%M", short=True)
        other = dt.datetime.fromtimestamp(t, tz).date()
        return text if other == day else f"{text} ({'the day before' if other < day else other.isoformat()})"

    items = []
    for p in pauses:
        if p.ended is None and p.end_unix >= now and p.until_unix > now:
            how = f"still paused when this report was made (until {at(p.until_unix)})"
            item = f"{at(p.since_unix)}–now"
        else:
            how = {"time": "resumed by time", "stopped": "ended when posed stopped",
                   "resumed": f"resumed by {p.resumed_by}" if p.resumed_by else "resumed when asked"}.get(
                p.ended, "its end was not recorded (posed stopped)")
            item = f"{at(p.since_unix)}–{at(p.end_unix)}"
        asked = f"asked by {p.by}" if p.by else "who asked was not said"
        items.append(html.escape(f"{item}, {asked}, {how}"))
    return (f"<p class='notice paused'>Watching paused for privacy: <b>{_hm(total)}</b> — " + "; ".join(items)
            + ".</p>")


def _falls_sentence(acct: DayTime, n_falls: int) -> str:
    """Falls said against the time posed was watching, never more."""
    off = None if not acct.known else acct.elapsed - acct.watching - acct.paused
    paused = f"paused for privacy for {_hm(acct.paused)}" if acct.paused > 0 else ""
    if n_falls:
        head = f"{n_falls} fall event(s) above."
        if off is not None and off >= 60:
            head += f" posed was not watching for {_hm(off)}: a fall then would not be here."
        if paused:
            head += f" Watching was {paused}: a fall then would not be here either."
        return head
    if not acct.known:
        return ("No fall was detected while posed was running; this history does not record when that was, so "
                "a fall while it was off would not be here either.")
    if acct.watching <= 0:
        return "<b class='warn'>posed was not watching this day: it cannot say whether anyone fell.</b>"
    text = f"No fall was detected in the {_hm(acct.watching)} posed was watching"
    if off >= 60 and paused:
        text += f"; it was {paused} and not watching for {_hm(off)}, when a fall would not have been seen"
    elif off >= 60:
        text += f"; it was not watching for {_hm(off)}, when a fall would not have been seen"
    elif paused:
        text += f"; it was {paused}, when a fall would not have been seen"
    return text + "."


def _method_html(down=None, paused: bool = False) -> str:
    pause = ("<p>Paused for privacy: someone at home asked posed to stop watching for a while (through the "
             "robot: voice, app or a button); posed looked at nothing until the pause ended by its time or was "
             "ended. Those minutes are counted apart: neither watched nor 'not watching'.</p>") if paused else ""
    return "".join(f"<p>{html.escape(p)}</p>" for p in posture.method_text(down)) + pause + (
        "<p>Watching: posed counts, minute by minute, the frames that came through it and the seconds with a "
        "person in view. A minute with no frame is 'not watching': posed was off or had no camera, and nothing "
        "that happened then is in this report. 'In view, posture not measured': a person was there, but the "
        "camera did not see enough of the body (both shoulders and both hips) to tell the posture.</p>"
        "<p>Joint-angle ranges: every stored sample counts in which the camera saw the joint's landmarks; an "
        "arm hidden from view is left out, not filled with the model's guess (histories written by a posed "
        "before this rule may still hold such values).</p>")


_CSS = """body{font-family:DejaVu Sans,Arial,sans-serif;max-width:1250px;margin:1.5em auto;color:#222}
h1{font-size:1.5em}h2{font-size:1.15em;margin-top:1.4em;border-bottom:1px solid #ccc}
table{border-collapse:collapse;margin:.5em 0}td,th{border:1px solid #ccc;padding:.25em .7em;text-align:left}
th{background:#f2f2f2}.meta,.small{color:#555;font-size:.9em}.warn{color:#c0392b}
.notice{background:#f6f6f6;border-left:4px solid #888;padding:.4em .8em}.notice.paused{border-left-color:#7e6fc0}"""
