"""``posed plot history [--since T] [--until T] [--panels torso,sagittal] -o FILE.png``: joint-angle plots."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from daemon.commands import add_config_args, config_from_args
from daemon.commands.history import add_range_args, open_history
from daemon.config.paths import EVENTS_FILE, events_path
from daemon.history.plot import PANELS, Mark, draw_history
from daemon.timeparse import iso


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("plot", help="draw stored data as a PNG")
    what = parser.add_subparsers(dest="what", metavar="WHAT", required=True)
    hist = what.add_parser("history", help="joint-angle trajectories (like the paper's Figures 12 and 16)")
    add_config_args(hist, source=False)
    add_range_args(hist)
    hist.add_argument("--panels", default="torso,sagittal",
                      help=f"comma-separated panels: {', '.join(PANELS)}, or angle names joined by '+' "
                           "(e.g. theta_hp_l+theta_kn_l)")
    hist.add_argument("--no-events", action="store_true", help="do not mark fall events")
    hist.add_argument("--width", type=int, default=1200, help="image width in pixels")
    hist.add_argument("-o", "--output", required=True, metavar="FILE.png", help="the image to write")
    hist.set_defaults(func=run)


def parse_panels(spec: str) -> list[tuple[str, tuple[str, ...]]]:
    from daemon.history.store import ANGLE_COLUMNS  # not at import: it pulls in structlog

    panels = []
    for item in filter(None, (s.strip() for s in spec.split(","))):
        if item in PANELS:
            panels.append((item, PANELS[item]))
            continue
        names = tuple(n.strip() for n in item.split("+") if n.strip())
        bad = [n for n in names if n not in ANGLE_COLUMNS]
        if bad or not names:
            raise ValueError(f"unknown panel or angle {item!r}; panels: {', '.join(PANELS)}; angles: "
                             f"{', '.join(ANGLE_COLUMNS)}")
        panels.append(("+".join(names), names))
    if not panels:
        raise ValueError("--panels is empty; e.g. --panels torso,sagittal")
    return panels


def run(args: argparse.Namespace) -> int:
    import cv2
    import numpy as np

    from daemon.history.store import ANGLE_COLUMNS
    from daemon.outbox.journal import EventJournal, JournalError

    out = Path(args.output)
    if out.suffix.lower() != ".png":
        print(f"posed plot history: {out} must end in .png", file=sys.stderr)
        return 2
    try:
        panels = parse_panels(args.panels)
        pipeline = None if args.db else config_from_args(args).pipeline
        hist, since, until = open_history(args, pipeline)
    except (ValueError, FileNotFoundError) as exc:
        print(f"posed plot history: {exc}", file=sys.stderr)
        return 2
    try:
        rows = list(hist.rows(since, until))
    finally:
        hist.close()
    if not rows:
        print("posed plot history: no joint angles stored for that time range (try a wider --since)",
              file=sys.stderr)
        return 1
    data = np.array([[np.nan if v is None else v for v in r] for r in rows], float)
    wall = data[:, 0]
    angles = {name: data[:, 4 + i] for i, name in enumerate(ANGLE_COLUMNS)}
    marks: list[Mark] = []
    if not args.no_events:
        path = Path(args.db).with_name(EVENTS_FILE) if args.db else events_path(pipeline)
        if path.is_file():
            try:
                with EventJournal(path, readonly=True) as journal:
                    marks = [Mark(s.wall, s.event.state) for s in journal.query(wall[0], wall[-1])]
            except (JournalError, FileNotFoundError) as exc:
                print(f"posed plot history: {exc}; --no-events draws the angles without the event marks",
                      file=sys.stderr)
                return 1
    image = draw_history(wall, angles, panels, marks, title=f"joint angles from {iso(wall[0])} UTC",
                         width=args.width)
    if not cv2.imwrite(str(out), image):
        print(f"posed plot history: cannot write {out} (does the folder exist and is it writable?)",
              file=sys.stderr)
        return 1
    print(f"{out}: {len(rows)} frames, {len(marks)} event marks", file=sys.stderr)
    return 0
