"""Joint-angle plots a person can read (matplotlib's Agg canvas drawn directly: no pyplot, no GUI, no global
backend state).

One panel per group of angles (``names.PANELS``), y in degrees, x the clock in the robot's local time zone
(``AngleSeries.clock``) or the time from the recording's first frame. Every line is named in plain words
("left knee flexion"); left is a solid line, right a dashed one (and the trunk's three angles solid, dash-dot
and dotted), so the sides can be told apart in grey print too. Not-measured samples are gaps, never 0. Fall
episodes are shaded from their first to their last message, numbered above the top panel (nearby episodes
share one label, ``falls 2-4``, so labels never overlap), and described one per line under the plot.
"""

from __future__ import annotations

import datetime as dt
import io
from collections.abc import Sequence

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.ticker import FixedFormatter, FixedLocator, FuncFormatter, MultipleLocator

from posed.viz.names import PANEL_TITLES, label, side
from posed.viz.series import AngleSeries, Episode

# one colour per joint family; the side is told by the line style
FAMILY_COLOURS = {"hp": "#1f5fa8", "kn": "#7b3294", "sh": "#2e8b57", "el": "#b8860b", "tr": "#333333",
                  "bd": "#7f6000"}
AXIS_STYLES = {"theta": "-", "phi": "-.", "psi": ":"}
FALL_COLOUR = "#d62728"
LABEL_LIFT_PT = 17.0   # fall numbers this far above the top panel: over its title, never on it
TIME_STEPS_S = (0.5, 1, 2, 5, 10, 15, 30, 60, 120, 300, 600, 900, 1800, 3600, 7200)
CLOCK_STEPS_S = (60, 120, 300, 600, 900, 1800, 3600, 7200, 10800, 21600, 43200)   # clock-axis ticks under a day


def offset_text(d: dt.datetime) -> str:
    """``UTC+01:00`` (``UTC`` for an unknown offset) of an aware date-time."""
    off = d.strftime("%z")
    return f"UTC{off[:3]}:{off[3:5]}" if off else "UTC"


def zone_changes(tz: dt.tzinfo, start: float, end: float) -> list[tuple[float, dt.datetime, dt.datetime]]:
    """Where the UTC offset of ``tz`` changes between two unix times (summer time begins or ends): (unix time of
    the change, the clock just before it, the clock at it), in order. Found hour by hour, then to the second
    (zones change their offset at most a few times a year)."""
    def offset(t: float):
        return dt.datetime.fromtimestamp(t, tz).utcoffset()

    out = []
    t, step = float(start), 3600.0
    while t < end:
        nxt = min(t + step, float(end))
        if offset(nxt) != offset(t):
            lo, hi = t, nxt
            while hi - lo > 0.5:
                mid = (lo + hi) / 2
                lo, hi = (mid, hi) if offset(mid) == offset(t) else (lo, mid)
            at = float(round(hi))
            out.append((at, dt.datetime.fromtimestamp(at - 1, tz) + dt.timedelta(seconds=1),
                        dt.datetime.fromtimestamp(at, tz)))
        t = nxt
    return out


def zone_text(tz: dt.tzinfo, at: float, until: float | None = None) -> str:
    """``Europe/Berlin, UTC+01:00`` (or the abbreviation when the zone has no IANA key); with ``until``, every
    change of the offset in between, the night the clocks go back or forward: ``Europe/London, UTC+01:00 until
    02:00, when the clocks went back to 01:00 (UTC)`` (the date too when the span is longer than a day)."""
    d = dt.datetime.fromtimestamp(at, tz)
    key = getattr(tz, "key", None) or d.tzname() or ""
    text = f"{key}, {offset_text(d)}" if key else offset_text(d)
    changes = zone_changes(tz, at, until) if until is not None else []
    dated = until is not None and until - at > 90000.0
    for _, before, after in changes[:6]:
        way = "forward" if after.utcoffset() > before.utcoffset() else "back"
        when = before.strftime("%Y-%m-%d %H:%M" if dated else "%H:%M")
        text += f"; from {when} the clocks went {way} to {after:%H:%M} ({offset_text(after)})"
    if len(changes) > 6:
        text += f"; and {len(changes) - 6} more changes of the offset"
    return text


def clock(t: float, tz: dt.tzinfo, fmt: str = "%H:%M:%S", short: bool = False) -> str:
    """``t`` as the robot's clock read it (``fmt``), with the zone's abbreviation and offset when that clock
    time happened twice (the hour the clocks go back): ``01:30:00 BST (UTC+01:00)``, then ``01:30:00 GMT
    (UTC)``; ``short``: only the abbreviation (the offset when the zone has no letters for it)."""
    d = dt.datetime.fromtimestamp(t, tz)
    text = d.strftime(fmt)
    if d.replace(fold=1 - d.fold).utcoffset() == d.utcoffset():
        return text
    abbr = d.tzname() or ""
    named = abbr.isalpha()
    if short:
        return f"{text} {abbr if named else offset_text(d)}"
    return f"{text} {abbr} ({offset_text(d)})" if named else f"{text} ({offset_text(d)})"


def time_formatter(series: AngleSeries, tz: dt.tzinfo):
    """A function formatting one time of ``series`` for the text (clock ``14:03:05``, with the date when the
    series covers more than one day of the robot's clock and the offset in an hour the clocks went back over;
    or ``1:23.4`` from a recording's first frame)."""
    if series.clock:
        days = {dt.datetime.fromtimestamp(float(t), tz).date() for t in (series.time[:1], series.time[-1:])
                for t in t}
        fmt = "%Y-%m-%d %H:%M:%S" if len(days) > 1 else "%H:%M:%S"
        return lambda t: clock(t, tz, fmt)
    return lambda t: f"{int(t // 60)}:{t % 60:04.1f}"


def _style(name: str) -> dict:
    parts = name.split("_")
    family = parts[1] if len(parts) > 1 else ""
    if family in ("tr", "bd"):
        return {"color": FAMILY_COLOURS[family], "linestyle": AXIS_STYLES.get(parts[0], "-")}
    return {"color": FAMILY_COLOURS.get(family, "#555555"), "linestyle": "--" if side(name) == "right" else "-"}


def _x(series: AngleSeries, t: np.ndarray) -> np.ndarray:
    return t / 86400.0 if series.clock else t      # matplotlib dates: days since 1970-01-01 UTC


def plot_angles(series: AngleSeries, panels: Sequence[tuple[str, Sequence[str]]], falls: Sequence[Episode],
                *, title: str, tz: dt.tzinfo | None = None, width_px: int = 1400, dpi: int = 110,
                acks: bool = True) -> bytes:
    """The PNG bytes of the angle plot (``angle_figure``)."""
    fig = angle_figure(series, panels, falls, title=title, tz=tz, width_px=width_px, dpi=dpi, acks=acks)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    return buf.getvalue()


def angle_figure(series: AngleSeries, panels: Sequence[tuple[str, Sequence[str]]], falls: Sequence[Episode],
                 *, title: str, tz: dt.tzinfo | None = None, width_px: int = 1400, dpi: int = 110,
                 acks: bool = True) -> Figure:
    """The angle plot as a matplotlib Figure (Agg canvas). ``panels``: (panel key or title, angle names);
    ``falls`` on the same clock as ``series``; ``acks``: whether the falls' acknowledgements are known (a
    journal); ``tz`` the zone of a clock series (the commands pass ``daemon.timeparse.local_zone``'s), unused
    for a recording's time."""
    if series.clock and tz is None:
        raise ValueError("a clock series needs its time zone: pass tz (the robot's, daemon.timeparse.local_zone)")
    s = series.with_gaps()
    fmt = time_formatter(series, tz)
    n = len(panels)
    # one note per fall under the plot, wrapped to the figure's width (a restored or frameless alarm's note
    # is long): 9-point text is about 0.6 em a character
    import textwrap

    chars = max(40, int(width_px * 0.88 / (9 * dpi / 72 * 0.6)))
    lines = [line for i, ep in enumerate(falls, 1)
             for line in textwrap.wrap(f"fall {i}: {ep.describe(fmt, acks)}", chars, subsequent_indent="    ")]
    notes = len(lines)
    height_in = 2.5 * n + 1.2 + 0.22 * notes
    fig = Figure(figsize=(width_px / dpi, height_in), dpi=dpi)
    FigureCanvasAgg(fig)
    bottom = (0.55 + 0.22 * notes) / height_in + 0.05
    axes = fig.subplots(n, 1, sharex=True, squeeze=False)[:, 0]
    fig.subplots_adjust(left=0.07, right=0.76, top=1 - 0.95 / height_in, bottom=bottom, hspace=0.28)
    x = _x(s, s.time)
    for ax, (key, names) in zip(axes, panels, strict=True):
        drawn = 0
        for name in names:
            v = s.angles.get(name)
            if v is None or not np.any(np.isfinite(v)):
                continue
            ax.plot(x, v, linewidth=1.4, label=label(name), **_style(name))
            drawn += 1
        ax.set_title(PANEL_TITLES.get(key, key), loc="left", fontsize=10)
        ax.set_ylabel("degrees")
        ax.grid(True, color="#dddddd", linewidth=0.6)
        if drawn:
            ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8.5, frameon=False)
        else:
            ax.text(0.5, 0.5, "not measured in this time range", transform=ax.transAxes, ha="center",
                    va="center", color="#888888")
            ax.set_yticks([])
        for ep in falls:
            x0, x1 = _x(s, np.array([ep.start, ep.end]))
            ax.axvspan(x0, max(x1, x0), color=FALL_COLOUR, alpha=0.12, linewidth=0)
            ax.axvline(x0, color=FALL_COLOUR, linewidth=1.2)
    if len(s.time):
        lo, hi = _x(s, np.array([s.time.min(), s.time.max()]))
        for ep in falls:
            lo, hi = min(lo, _x(s, np.array([ep.start]))[0]), max(hi, _x(s, np.array([ep.end]))[0])
        pad = (hi - lo) * 0.01 or (1.0 / 86400 if s.clock else 1.0)
        axes[0].set_xlim(lo - pad, hi + pad)
    _number_falls(axes[0], s, falls)
    bottom_ax = axes[-1]
    if s.clock:
        # whole clock times of the robot's zone, found in unix time: the night the clocks go back both 01:00
        # are ticks (01:00 BST, 01:00 GMT), the hour they skip none (matplotlib's date locator, which steps the
        # wall clock, left most of such a night without a tick)
        lo, hi = (v * 86400.0 for v in axes[0].get_xlim())
        ticks = clock_ticks(tz, lo, hi)
        bottom_ax.xaxis.set_major_locator(FixedLocator([t / 86400.0 for t in ticks]))
        bottom_ax.xaxis.set_major_formatter(FixedFormatter(clock_tick_labels(ticks, tz)))
        at = float(s.time[0]) if len(s.time) else 0.0
        bottom_ax.set_xlabel(f"clock time of the robot ({zone_text(tz, at, float(s.time[-1]) if len(s.time) else None)})")
    else:
        lo, hi = axes[0].get_xlim()
        step = recording_time_step(hi - lo)
        bottom_ax.xaxis.set_major_locator(MultipleLocator(step))
        bottom_ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: recording_time(v, step)))
        bottom_ax.set_xlabel("time in the recording (minutes:seconds from its first frame; a fit file has no "
                             "clock time)")
    fig.suptitle(title, x=0.07, ha="left", fontsize=12)
    for i, line in enumerate(lines, 1):
        fig.text(0.07, (0.12 + 0.22 * (notes - i)) / height_in, line, fontsize=9, color=FALL_COLOUR)
    return fig


def clock_ticks(tz: dt.tzinfo, lo: float, hi: float, max_ticks: int = 10) -> list[float]:
    """Unix times between ``lo`` and ``hi`` at which the robot's clock (``tz``) reads a whole step (a minute to
    12 hours; whole days for longer spans) — at most about ``max_ticks`` of them. Found in unix time, minute
    by minute, so a clock time that happens twice (the hour the clocks go back) is a tick twice and one that
    never happens (the hour they skip) is none."""
    if hi <= lo:
        return []
    step = next((s for s in CLOCK_STEPS_S if (hi - lo) / s <= max_ticks), None)
    if step is None:
        days = max(1, int(np.ceil((hi - lo) / 86400.0 / max_ticks)))
        d = dt.datetime.fromtimestamp(lo, tz).date()
        out = []
        while True:
            t = dt.datetime.combine(d, dt.time(0), tz).timestamp()
            if t > hi:
                return out
            if t >= lo and d.toordinal() % days == 0:
                out.append(t)
            d += dt.timedelta(days=1)
    out = []
    t = float(np.ceil(lo / 60.0) * 60.0)
    while t <= hi:
        c = dt.datetime.fromtimestamp(t, tz)
        if c.second == 0 and (c.hour * 3600 + c.minute * 60) % step == 0:
            out.append(t)
        t += 60.0
    return out


def clock_tick_labels(ticks: Sequence[float], tz: dt.tzinfo) -> list[str]:
    """``14:30`` per tick (``01:00 BST`` / ``01:00 GMT`` in the hour the clocks go back), the date under the
    first tick and under each midnight; only the date when the ticks are whole days apart."""
    clocks = [dt.datetime.fromtimestamp(t, tz) for t in ticks]
    if len(clocks) > 1 and all(c.time() == dt.time(0) for c in clocks):
        return [f"{c:%Y-%m-%d}" for c in clocks]
    out = []
    for i, (t, c) in enumerate(zip(ticks, clocks, strict=True)):
        text = clock(t, tz, "%H:%M", short=True)
        out.append(f"{text}\n{c:%Y-%m-%d}" if i == 0 or (c.hour, c.minute) == (0, 0) else text)
    return out


def recording_time_step(span_s: float, max_ticks: int = 10) -> float:
    """The tick step for ``span_s`` seconds of recording time: the smallest of ``TIME_STEPS_S`` giving at most
    ``max_ticks`` ticks (a step the labels can tell apart: ``recording_time`` shows tenths below 1 s)."""
    return next((s for s in TIME_STEPS_S if span_s / s <= max_ticks), TIME_STEPS_S[-1])


def recording_time(t: float, step: float) -> str:
    """``m:ss`` (``m:ss.s`` when the ticks are less than a second apart) of ``t`` seconds."""
    sign = "-" if t < -1e-9 else ""
    t = abs(t)
    if step < 1:
        t = round(t, 1)
        return f"{sign}{int(t // 60)}:{t % 60:04.1f}"
    t = round(t)
    return f"{sign}{int(t // 60)}:{int(t % 60):02d}"


def _number_falls(ax, s: AngleSeries, falls: Sequence[Episode]) -> None:
    """Episode numbers above the top panel. Episodes closer together than a label's width share one label
    (``falls 2-4``), centred on them: two labels are then always more than a label's width apart, so they
    never overlap, however many falls there are."""
    if not falls:
        return
    lo, hi = ax.get_xlim()
    span = (hi - lo) or 1.0
    fig = ax.get_figure()
    axes_px = ax.get_position().width * fig.get_figwidth() * fig.dpi
    fontsize = 8.5
    width = (len("falls 88-88") * 0.62 * fontsize * fig.dpi / 72.0 + 8.0) / axes_px   # axes fraction
    xs = [(_x(s, np.array([ep.start]))[0] - lo) / span for ep in falls]
    clusters: list[list[int]] = []
    for i, xf in enumerate(xs):
        if clusters and xf - xs[clusters[-1][-1]] < width:
            clusters[-1].append(i)
        else:
            clusters.append([i])
    for members in clusters:
        first, last = members[0] + 1, members[-1] + 1
        text = f"fall {first}" if first == last else f"falls {first}-{last}"
        xc = float(np.mean([xs[i] for i in members]))
        # in a band of their own above the panel's title (which is at the left, at the axes' top)
        ax.annotate(text, (xc, 1.0), xycoords="axes fraction", xytext=(0, LABEL_LIFT_PT), textcoords="offset points",
                    ha="center", va="bottom", fontsize=fontsize, color="white",
                    bbox={"boxstyle": "round,pad=0.2", "fc": FALL_COLOUR, "ec": "none"})
