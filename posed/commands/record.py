"""``posed record --source URI -o PATH [--seconds N]``: save what a source sees, for replay with file:PATH.

The output name picks the format (hal/recorder.py): ``.mkv`` lossless video, ``.avi``/``.mp4`` small video
(each with ``NAME.timestamps.jsonl``), ``.db3`` a RealSense recording with depth, no suffix a folder of PNGs.
Prints one JSON summary line on stdout; logs go to stderr. Ctrl-C or SIGTERM stops and finishes the file.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import sys
from pathlib import Path

from posed import hal
from posed.commands import add_config_args, config_from_args
from posed.daemon import logs


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("record", help="save what a camera or recording sees (video + timestamps, or .db3 "
                                           "with depth) so that it can be replayed with --source file:PATH")
    add_config_args(parser, example="source.width=1280")
    parser.add_argument("-o", "--output", required=True, metavar="PATH",
                        help="NAME.mkv (lossless), NAME.avi, NAME.mp4, NAME.db3 (RealSense, keeps depth) or a folder")
    parser.add_argument("--seconds", type=float, metavar="N", help="stop after N seconds (default: until Ctrl-C "
                                                                   "or the end of a recording)")
    parser.add_argument("--frames", type=int, metavar="N", help="stop after N frames")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    config = config_from_args(args)
    logs.configure(config.logging.level, config.logging.format, stream=sys.stderr)
    log = logs.get("record")
    if args.seconds is not None and args.seconds <= 0:
        print("posed record: --seconds must be > 0", file=sys.stderr)
        return os.EX_USAGE
    try:
        hal.check_output(args.output)
    except hal.SourceError as exc:
        print(f"posed record: {exc}", file=sys.stderr)
        return os.EX_USAGE
    try:
        source = hal.open_source(config.source)
        source.open()
    except hal.SourceError as exc:
        print(f"posed record: {exc}", file=sys.stderr)
        return os.EX_NOINPUT if isinstance(exc, hal.SourceNotFound) else os.EX_UNAVAILABLE
    stopping = {"now": False}

    def on_term(signum, frame):
        stopping["now"] = True

    previous = signal.signal(signal.SIGTERM, on_term)
    log.info("record.start", source=source.name, output=args.output, seconds=args.seconds)
    try:
        summary = hal.record(source, args.output, seconds=args.seconds, max_frames=args.frames,
                             should_stop=lambda: stopping["now"])
    except (hal.SourceError, OSError) as exc:
        print(f"posed record: cannot write {args.output}: {exc}", file=sys.stderr)
        return os.EX_CANTCREAT
    finally:
        source.close()
        signal.signal(signal.SIGTERM, previous)
    log.info("record.done", **summary.to_json())
    print(json.dumps(summary.to_json()))
    if summary.reason == "disk full":      # hal.record stopped before a frame the disk could not take
        out = Path(args.output)
        folder = out if out.suffix == "" else out.parent
        print(f"posed record: disk full at {os.path.abspath(folder)} after {summary.frames} frames: free space or "
              "record elsewhere", file=sys.stderr)
        return os.EX_CANTCREAT
    if summary.frames == 0:
        print(f"posed record: no frame was recorded from {source.name} ({summary.reason})", file=sys.stderr)
        return 1
    return 0
