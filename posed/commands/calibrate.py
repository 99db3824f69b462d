"""``posed calibrate RECORDING.landmarks.jsonl -o user.yaml [--height M]``: per-user link lengths.

The person stands facing the camera, arms down, for at least 10 frames (paper section 3, step 1). The output
is the flat ``key: value`` calibration file of :mod:`fitting.body` (valid YAML, read by the fit with the
standard library); point ``fitting.calibration`` at it. Exit status: 0 written, 1 not enough usable frames or
implausible lengths, 2 the recording cannot be read, the output is the recording (or the config file) or the
file cannot be created, 74 the disk is full (the partial file is removed).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import yaml

from posed.commands import add_config_args, config_from_args, error_printer
from posed.commands._paths import config_inputs, file_write_failed, refuse_same_file


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("calibrate", help="measure a person's link lengths from a standing recording")
    parser.add_argument("input", metavar="RECORDING.landmarks.jsonl",
                        help="landmark recording of the person standing, facing the camera, arms down")
    parser.add_argument("-o", "--output", metavar="user.yaml", required=True, help="calibration file to write")
    parser.add_argument("--height", type=float, default=None, metavar="M",
                        help="the person's body height in metres (default: fitting.body_height_m)")
    add_config_args(parser, source=False)
    parser.set_defaults(func=run)


_err = error_printer("posed calibrate")


def run(args: argparse.Namespace) -> int:
    from posed.fitting import CalibrationFailed, calibrate, read_calibration, write_calibration
    from posed.landmarks import RecordingError, RecordingProblem, iter_recording

    refused = refuse_same_file("posed calibrate", args.output,
                               [("recording", args.input), *config_inputs(args)])
    if refused is not None:
        return refused
    cfg = config_from_args(args).fitting
    height = args.height if args.height is not None else cfg.body_height_m
    if not 0.8 <= height <= 2.3:
        _err(f"--height {height} m is not a plausible body height (0.8..2.3 m)")
        return 2
    try:
        _header, stream = iter_recording(args.input)
    except RecordingError as exc:
        _err(str(exc))
        return 2
    frames = []
    for item in stream:
        if isinstance(item, RecordingProblem):
            print(str(item), file=sys.stderr, flush=True)
            continue
        frames.append(item.landmarks)
    try:
        report = calibrate(frames, height)
    except CalibrationFailed as exc:
        _err(str(exc))
        return 1
    out = Path(args.output)
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        write_calibration(out, report.dims, report.frames_used, source=str(args.input))
    except OSError as exc:
        return file_write_failed("posed calibrate", out, exc)
    # the file must read back both as YAML and with the fit's own reader
    yaml.safe_load(out.read_text(encoding="utf-8"))
    read_calibration(out)
    spread = ", ".join(f"{k} {v:.1%}" for k, v in report.spread.items())
    _err(f"{out}: {report.frames_used} of {report.frames_total} frames used; frame-to-frame spread: {spread}")
    return 0
