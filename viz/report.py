"""The daily summary for a caregiver: one self-contained HTML file (tables, and PNG pictures inlined as
base64: it opens offline, can be mailed, and loads nothing from anywhere).

What it holds: time spent standing, sitting, lying and not seen (``viz.posture``, whose rules and limits
are printed in the report), sit-to-stand transitions, walking bouts, the falls and how each ended
(recovered, alarm, acknowledged), the day's joint-angle ranges, a posture timeline and the angle plot.
"""

from __future__ import annotations

import base64
import datetime as dt
import html
import io
from collections.abc import Sequence

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from posed.viz import posture
from posed.viz.names import MEASURED_ANGLES, PANELS, short_label
from posed.viz.plots import FALL_COLOUR, plot_angles, zone_text
from posed.viz.series import AngleSeries, Episode

BODY_ANGLES = ("theta_bd", "phi_bd", "psi_bd")

MIN_BAR_S = 120.0   # a stretch is drawn at least this wide on the day's bar, so a short one still shows
POSTURE_STYLE = {"standing": ("#4c9f70", ""), "sitting": ("#e0a030", "//"), "lying": ("#c0392b", "xx")}


def _png_tag(png: bytes, alt: str) -> str:
    return (f'<img alt="{html.escape(alt)}" style="max-width:100%" '
            f'src="data:image/png;base64,{base64.b64encode(png).decode()}">')


def _hm(seconds: float) -> str:
    m = int(round(seconds / 60.0))
    return f"{m // 60} h {m % 60:02d} min" if m >= 60 else (f"{m} min" if m else f"{seconds:.0f} s")


def timeline_png(summary: posture.DaySummary, falls: Sequence[Episode], span: tuple[float, float],
                 tz: dt.tzinfo, width_px: int = 1200, dpi: int = 110) -> bytes:
    """The day as one bar: each posture a colour and a hatch (readable without colour), fall starts as red
    numbered lines, hours on the x axis."""
    from matplotlib import dates as mdates

    fig = Figure(figsize=(width_px / dpi, 1.9), dpi=dpi)
    FigureCanvasAgg(fig)
    ax = fig.add_axes((0.04, 0.36, 0.8, 0.36))
    for r in summary.runs:
        colour, hatch = POSTURE_STYLE[r.posture]
        ax.broken_barh([(r.start / 86400.0, max(r.seconds, MIN_BAR_S) / 86400.0)], (0, 1), facecolors=colour,
                       hatch=hatch, edgecolor="white", linewidth=0)
    for i, ep in enumerate(falls, 1):
        x = ep.start / 86400.0
        ax.axvline(x, color=FALL_COLOUR, linewidth=1.5)
        ax.text(x, 1.06 + 0.3 * ((i - 1) % 2), f"fall {i}", color=FALL_COLOUR, ha="center", fontsize=8,
                transform=ax.get_xaxis_transform())
    ax.set_xlim(span[0] / 86400.0, span[1] / 86400.0)
    ax.set_ylim(0, 1)
    ax.set_yticks([])
    loc = mdates.HourLocator(byhour=range(0, 24, 2), tz=tz)
    ax.xaxis.set_major_locator(loc)
    ax.xaxis.set_major_formatter(mdates.DateFormatter("%H:%M", tz=tz))
    ax.set_xlabel(f"clock time of the robot ({zone_text(tz, span[0])}); white = not seen; stretches shorter "
                  f"than {MIN_BAR_S / 60:.0f} min are drawn {MIN_BAR_S / 60:.0f} min wide", fontsize=9)
    handles = [Patch(facecolor=c, hatch=h, edgecolor="white", label=p) for p, (c, h) in POSTURE_STYLE.items()]
    fig.legend(handles=handles, loc="center left", bbox_to_anchor=(0.85, 0.6), frameon=False, fontsize=9)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
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
               sources: str, max_step_s: float = 1.0) -> str:
    """The HTML text of the day's report. ``series`` on the robot's clock (unix seconds), ``falls`` the
    day's episodes (journal), ``sources`` a line naming the files it was made from."""
    start = dt.datetime.combine(day, dt.time(0), tz).timestamp()
    end = dt.datetime.combine(day + dt.timedelta(days=1), dt.time(0), tz).timestamp()
    span = (start, end)
    summary = posture.summarise(series.time, series.angles, span, max_step_s)

    def fmt(t: float) -> str:
        return dt.datetime.fromtimestamp(t, tz).strftime("%H:%M:%S")

    esc = html.escape
    parts = [f"<!doctype html><html lang='en'><head><meta charset='utf-8'><title>posed: {esc(robot)}, "
             f"{day.isoformat()}</title><style>{_CSS}</style></head><body>",
             f"<h1>Daily summary, {day.strftime('%A %d %B %Y')}</h1>",
             f"<p class='meta'>Robot <b>{esc(robot)}</b>; clock: the robot's local time ({esc(zone_text(tz, start))})."
             f" Made from {esc(sources)}.</p>"]
    seen = sum(summary.seconds[p] for p in posture.POSTURES)
    parts.append("<h2>Time by posture</h2><table><tr><th>posture</th><th>time</th><th>share of the time seen"
                 "</th></tr>")
    for p in (*posture.POSTURES, "not seen"):
        share = f"{100 * summary.seconds[p] / seen:.0f} %" if p != "not seen" and seen > 0 else ""
        parts.append(f"<tr><td>{p}</td><td>{_hm(summary.seconds[p])}</td><td>{share}</td></tr>")
    parts.append("</table>")
    parts.append(_png_tag(timeline_png(summary, falls, span, tz), "posture over the day"))
    walk_s = sum(b.seconds for b in summary.walking_bouts)
    parts.append("<h2>Activity</h2><table>"
                 f"<tr><td>sit-to-stand transitions</td><td>{summary.sit_to_stand}</td></tr>"
                 f"<tr><td>walking bouts</td><td>{len(summary.walking_bouts)} ({_hm(walk_s)} in all)</td></tr>"
                 "</table>")
    if summary.walking_bouts:
        parts.append("<p class='small'>Walking bouts: " + ", ".join(
            f"{fmt(b.start)} ({b.seconds:.0f} s)" for b in summary.walking_bouts[:30]) + "</p>")
    parts.append("<h2>Falls</h2>")
    if falls:
        parts.append("<table><tr><th></th><th>started</th><th>what happened</th><th>how it ended</th>"
                     "<th>acknowledged</th></tr>")
        for i, ep in enumerate(falls, 1):
            what = " &rarr; ".join(esc(s.replace("_", " ")) for s in ep.states)
            ack = fmt(ep.acked) if ep.acked is not None else "<b class='warn'>no</b>"
            parts.append(f"<tr><td>fall {i}</td><td>{fmt(ep.start)}</td><td>{what}</td><td>{esc(ep.outcome)}"
                         f"</td><td>{ack}</td></tr>")
        parts.append("</table>")
    else:
        parts.append("<p>No fall was detected this day.</p>")
    parts.append("<h2>Joint-angle ranges</h2><p class='small'>Degrees over the day's measured samples "
                 "(flexion positive; angles the model does not measure are left out).</p>"
                 "<table><tr><th>angle</th><th>samples</th><th>min</th><th>5 %</th><th>median</th>"
                 "<th>95 %</th><th>max</th></tr>")
    for name, n, *vals in angle_ranges(series):
        parts.append(f"<tr><td>{esc(name)}</td><td>{n}</td>" + "".join(f"<td>{v:.0f}</td>" for v in vals)
                     + "</tr>")
    parts.append("</table>")
    if len(series.time):
        png = plot_angles(series, [(k, PANELS[k]) for k in ("legs", "trunk")], falls, tz=tz,
                          title="Hips, knees and trunk over the day")
        parts.append("<h2>Joint angles</h2>" + _png_tag(png, "joint angles over the day"))
    parts.append("<h2>How this is worked out</h2><div class='small'>" + _method_html() + "</div>")
    parts.append("</body></html>")
    return "\n".join(parts)


def _method_html() -> str:
    return "".join(f"<p>{html.escape(p)}</p>" for p in posture.method_text()) + (
        "<p>Joint-angle ranges: every stored sample with a fit counts. The history stores the fitted angles "
        "without saying which ones the camera actually saw in that frame, so an arm hidden from view still "
        "has the model's value; a fit file (posed plot fit) leaves those out.</p>")


_CSS = """body{font-family:DejaVu Sans,Arial,sans-serif;max-width:1250px;margin:1.5em auto;color:#222}
h1{font-size:1.5em}h2{font-size:1.15em;margin-top:1.4em;border-bottom:1px solid #ccc}
table{border-collapse:collapse;margin:.5em 0}td,th{border:1px solid #ccc;padding:.25em .7em;text-align:left}
th{background:#f2f2f2}.meta,.small{color:#555;font-size:.9em}.warn{color:#c0392b}"""
