"""``posed plot history|fit ... -o FILE.png``: joint-angle plots a person can read (viz.plots, matplotlib).

``posed plot history [--since T] [--until T]``: the joint-angle history database; x is the robot's clock in
its local time zone (``--tz`` another), fall events from the journal beside it. ``posed plot fit FIT.jsonl``:
a ``posed fit`` output; a fit file carries only capture times (seconds from the recording's first frame), so
x is that time unless ``--start`` gives the clock time of the first frame; fall events from a ``posed falls``
output (``--events``), on the same capture clock.

Exit status: 0 drawn, 1 nothing to draw or some lines skipped, 2 a bad option or input (a file that is not fit
results, e.g. a landmark recording; an output that is an input), 74 writing the image failed (a full disk: the
partial file is removed).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from posed.commands import add_config_args, bounded_int, config_from_args, config_path, read_jsonl
from posed.commands._paths import Output, OutputError, config_inputs, refuse_same_file, sniff
from posed.commands.history import add_range_args, history_path, open_history
from posed.daemon.config.paths import EVENTS_FILE
from posed.viz.names import PANELS

# the older panel names, still accepted
PANEL_ALIASES = {"torso": ("trunk",), "sagittal": ("arms", "legs")}
DEFAULT_PANELS = "legs,trunk,arms"
MIN_WIDTH_PX, MAX_WIDTH_PX = 200, 10000     # narrower has no room for the panels; wider is a poster


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("plot", help="draw joint angles (history database or a fit file) as a PNG")
    what = parser.add_subparsers(dest="what", metavar="WHAT", required=True)
    hist = what.add_parser("history", help="joint angles from the history database, on the robot's clock, "
                                           "with the fall events")
    add_config_args(hist, source=False, example="pipeline.state_dir=/var/lib/posed")
    add_range_args(hist)
    _common(hist)
    hist.add_argument("--no-events", action="store_true", help="do not mark fall events")
    hist.set_defaults(func=run)
    fit = what.add_parser("fit", help="joint angles of a `posed fit` output (a recording)")
    fit.add_argument("input", metavar="FIT.jsonl", help="fit results (posed fit -o FIT.jsonl)")
    fit.add_argument("--start", metavar="TIME", help="clock time of the recording's first frame (e.g. "
                                                     "2024-05-01T14:30:05); without it x is the recording time")
    fit.add_argument("--person", type=int, metavar="ID",
                     help="with several people in the file (results with `person`, a track id): whose angles to "
                          "plot (default: the person with the most frames)")
    fit.add_argument("--events", metavar="EVENTS.jsonl",
                     help="fall-event messages on the recording's capture clock (posed falls output)")
    _common(fit)
    fit.set_defaults(func=run_fit)


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument("--panels", default=DEFAULT_PANELS,
                   help=f"comma-separated panels: {', '.join(PANELS)}, or angle names joined by '+' "
                        "(e.g. theta_hp_l+theta_kn_l)")
    p.add_argument("--tz", metavar="ZONE", help="time zone of the clock axis (IANA name, e.g. Europe/Berlin; "
                                                "default: this machine's, the robot's)")
    p.add_argument("--width", type=bounded_int(MIN_WIDTH_PX, MAX_WIDTH_PX, "pixels"), default=1200,
                   help=f"image width in pixels ({MIN_WIDTH_PX} to {MAX_WIDTH_PX}; default 1200)")
    p.add_argument("-o", "--output", required=True, metavar="FILE.png", help="the image to write")


def parse_panels(spec: str) -> list[tuple[str, tuple[str, ...]]]:
    from posed.fitting import BODY_ANGLE_NAMES, JOINT_ANGLE_NAMES
    from posed.viz.names import MEASURED_ANGLES

    known = [n for n in JOINT_ANGLE_NAMES + BODY_ANGLE_NAMES if n in MEASURED_ANGLES]
    panels = []
    for item in filter(None, (s.strip() for s in spec.split(","))):
        if item in PANELS or item in PANEL_ALIASES:
            panels += [(k, PANELS[k]) for k in PANEL_ALIASES.get(item, (item,))]
            continue
        names = tuple(n.strip() for n in item.split("+") if n.strip())
        bad = [n for n in names if n not in known]
        if bad or not names:
            raise ValueError(f"unknown panel or angle {item!r}; panels: {', '.join(PANELS)}; angles: "
                             f"{', '.join(known)} (the head, hip rotation and ankles are not measured)")
        panels.append(("+".join(names), names))
    if not panels:
        raise ValueError(f"--panels is empty; e.g. --panels {DEFAULT_PANELS}")
    return panels


def _prepare(args, cmd: str):
    """(panels, tz) or an exit status after reporting the problem."""
    from posed.daemon.timeparse import local_zone

    out = Path(args.output)
    if out.suffix.lower() != ".png":
        print(f"{cmd}: {out} must end in .png", file=sys.stderr)
        return 2
    try:
        return parse_panels(args.panels), local_zone(args.tz)
    except ValueError as exc:     # a bad --panels, or an unknown --tz (named with the fix)
        print(f"{cmd}: {exc}", file=sys.stderr)
        return 2


def _write(out: Path, png: bytes, cmd: str) -> int:
    """0 when the image is written, else the exit status after saying why (74: a full disk)."""
    sink = Output(cmd, out, binary=True)
    try:
        sink.open()
    except OSError as exc:
        return sink.open_failed(exc, status=1)
    try:
        sink.write(png)
        sink.close()
    except OutputError as exc:
        return sink.failed(exc.exc)
    finally:
        sink.discard()
    return 0


def run(args: argparse.Namespace) -> int:
    from posed.commands._history_series import angle_series, event_marks
    from posed.daemon.history.store import ANGLE_COLUMNS
    from posed.daemon.outbox.journal import EventJournal, JournalError
    from posed.viz.plots import plot_angles, zone_text
    from posed.viz.series import episodes

    cmd = "posed plot history"
    prepared = _prepare(args, cmd)
    if isinstance(prepared, int):
        return prepared
    panels, tz = prepared
    try:
        pipeline = None if args.db else config_from_args(args).pipeline
        db = Path(args.db) if args.db else history_path(pipeline, config_path(args))
        refused = refuse_same_file(cmd, args.output, [("history database", db),
                                                      ("event journal", db.with_name(EVENTS_FILE)),
                                                      *config_inputs(args)])
        if refused is not None:
            return refused
        hist, since, until = open_history(args, pipeline, tz)
    except (ValueError, FileNotFoundError) as exc:
        print(f"{cmd}: {exc}", file=sys.stderr)
        return 2
    try:
        rows = list(hist.rows(since, until))
    except ValueError as exc:       # HistoryFileError: damage found while reading the rows
        print(f"{cmd}: {exc}", file=sys.stderr)
        return 2
    finally:
        hist.close()
    if not rows:
        print(f"{cmd}: no joint angles stored for that time range (try a wider --since)", file=sys.stderr)
        return 1
    series = angle_series(rows, ANGLE_COLUMNS)
    falls = []
    if not args.no_events:
        path = (Path(args.db) if args.db else history_path(pipeline, config_path(args))).with_name(EVENTS_FILE)
        if path.is_file():
            try:
                with EventJournal(path, readonly=True) as journal:
                    # every message of each event seen in the span: an alarm raised after the camera stopped
                    # (without frames) comes after the last stored sample, and is part of that fall
                    ids = dict.fromkeys(m.event.id for m in journal.query(series.time[0], series.time[-1]))
                    falls = episodes(event_marks([m for i in ids for m in journal.get(i)]))
            except FileNotFoundError:   # gone, or being created by the daemon this moment: no fall yet
                falls = []
            except JournalError as exc:
                print(f"{cmd}: {exc}; --no-events draws the angles without the event marks", file=sys.stderr)
                return 1
    import datetime as dt

    first, last = (dt.datetime.fromtimestamp(t, tz).strftime("%A %d %B %Y") for t in series.time[[0, -1]])
    span = first if last == first else f"{first} to {last}"     # more than one day: never only the first
    png = plot_angles(series, panels, falls, tz=tz, width_px=args.width,
                      title=f"Joint angles, {span} (robot clock, {zone_text(tz, series.time[0])})")
    status = _write(Path(args.output), png, cmd)
    if status:
        return status
    print(f"{args.output}: {len(rows)} frames, {len(falls)} fall event(s)", file=sys.stderr)
    return 0


def run_fit(args: argparse.Namespace) -> int:
    from posed.falls import FallEvent
    from posed.fitting import FitResult
    from posed.viz.plots import plot_angles
    from posed.viz.series import AngleSeries, EventMark, episodes

    cmd = "posed plot fit"
    prepared = _prepare(args, cmd)
    if isinstance(prepared, int):
        return prepared
    panels, tz = prepared
    try:
        start = _start_time(args.start, tz) if args.start else None
    except ValueError as exc:
        print(f"{cmd}: --start: {exc}", file=sys.stderr)
        return 2
    refused = refuse_same_file(cmd, args.output, [("fit results", args.input), ("events file", args.events)])
    if refused is not None:
        return refused
    results, problems = _read_jsonl(args.input, FitResult.from_json, cmd, "fit results")
    if results is None:
        return 2
    if not results:
        print(f"{cmd}: {args.input} holds no fit result", file=sys.stderr)
        return 2
    results, who = _one_person(results, args.person, args.input, cmd)
    if results is None:
        return 2
    results.sort(key=lambda r: r.t)
    t0 = results[0].t
    series = AngleSeries.from_fits(results, start)
    falls = []
    if args.events:
        events, bad = _read_jsonl(args.events, FallEvent.from_json, cmd, "fall events")
        if events is None:
            return 2
        problems += bad
        shift = (start - t0) if start is not None else -t0
        falls = episodes(EventMark(e.id, e.state, e.t_detect + shift) for e in events)
    ok = sum(r.ok for r in results)
    png = plot_angles(series, panels, falls, tz=tz, width_px=args.width, acks=False,
                      title=f"Joint angles of {Path(args.input).name}{who} ({ok} of {len(results)} frames fitted)")
    status = _write(Path(args.output), png, cmd)
    if status:
        return status
    print(f"{args.output}: {len(results)} frames, {len(falls)} fall event(s)", file=sys.stderr)
    return 1 if problems else 0


def _one_person(results: list, person: int | None, path: str, cmd: str):
    """The results of one person (``posed fit`` writes a line per person per frame, each with ``person``, when
    the recording followed several): ``person``'s, else the person with the most frames, so that no curve
    jumps from one body to another. A file without ``person`` is one person's. (results or None, title part)."""
    from collections import Counter

    counts = Counter(r.extra.get("person") for r in results if r.extra.get("person") is not None)
    if not counts:
        if person is not None:
            print(f"{cmd}: --person {person}: {path} holds one person's results (no `person` in them)",
                  file=sys.stderr)
            return None, ""
        return results, ""
    if person is None:
        person = counts.most_common(1)[0][0]
        if len(counts) > 1:
            others = ", ".join(f"{i} ({n} frames)" for i, n in sorted(counts.items()) if i != person)
            print(f"{cmd}: {path} holds {len(counts)} people; plotting person {person} ({counts[person]} frames); "
                  f"--person ID plots another: {others}", file=sys.stderr)
    elif person not in counts:
        print(f"{cmd}: --person {person}: no such person in {path}; the people are "
              + ", ".join(f"{i} ({n} frames)" for i, n in sorted(counts.items())), file=sys.stderr)
        return None, ""
    return [r for r in results if r.extra.get("person") == person], f", person {person}"


def _start_time(text: str, tz) -> float:
    """``--start``: an ISO date-time without an offset is in the plot's zone (``--tz``, else this machine's);
    anything else as ``--since`` takes it."""
    import datetime as dt

    from posed.daemon.timeparse import parse_time

    try:
        d = dt.datetime.fromisoformat(text.strip())
    except ValueError:
        return parse_time(text)
    return (d if d.tzinfo else d.replace(tzinfo=tz)).timestamp()


WRITTEN_BY = {"fit results": "posed fit REC.landmarks.jsonl -o FIT.jsonl",
              "fall events": "posed falls REC.landmarks.jsonl > EVENTS.jsonl"}


def _read_jsonl(path: str, parse, cmd: str, what: str):
    """(parsed objects, lines skipped), or (None, 0) when the file cannot be read at all or is plainly not
    ``what`` (a landmark recording, an image, binary data): said in one line."""
    kind, fmt = sniff(path)
    wrong = ""
    if kind == "landmarks":
        wrong = f"{path} is a landmark recording, not {what}"
        if what == "fit results":
            wrong += f": run `posed fit {path} -o FIT.jsonl` first and plot FIT.jsonl"
    elif kind in ("image", "video", "database"):
        wrong = f"{path} is {'an' if kind == 'image' else 'a'} {kind} ({fmt}), not {what} ({WRITTEN_BY[what]})"
    elif kind == "binary":
        wrong = f"{path} is not UTF-8 text, so not {what} ({WRITTEN_BY[what]})"
    if wrong:
        print(f"{cmd}: {wrong}", file=sys.stderr)
        return None, 0
    try:
        return read_jsonl(path, parse)
    except UnicodeDecodeError as exc:
        print(f"{cmd}: {path} is not UTF-8 text (byte 0x{exc.object[exc.start]:02x}), so not {what} "
              f"({WRITTEN_BY[what]})", file=sys.stderr)
        return None, 0
    except OSError as exc:
        print(f"{cmd}: cannot read {path}: {exc.strerror or exc}", file=sys.stderr)
        return None, 0
