"""``posed fit INPUT.landmarks.jsonl [-o OUTPUT.jsonl] [--mode video|image] [--config FILE]``: the 3D fit alone.

Reads a landmark recording (interfaces.md section 1) and writes one fit result per frame as JSON Lines
(interfaces.md section 2; standard output without ``-o``). Frames without a person, with missing, NaN or
low-visibility landmarks get ``"ok": false`` and a reason; a line that cannot be read is reported on stderr as
``FILE:LINE: message`` and skipped. The recording header's ``camera`` intrinsics, when present, select the
perspective model (``fitting.projection: auto``); without them the fit projects, as the daemon's does, through
the lens of ``falls.camera_hfov_deg`` assumed (the results say ``"lens": "assumed"`` and carry no
``root_cam_m``; ``fitting.projection: orthographic`` gives the paper's orthographic fit).

Exit status: 0 every line was read, 1 some lines were skipped, 2 the recording cannot be read at all.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from posed.commands import add_config_args, config_from_args, error_printer


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("fit", help="fit the 3D humanoid to a landmark recording (JSON Lines of fit results)")
    parser.add_argument("input", metavar="INPUT.landmarks.jsonl", help="landmark recording to fit")
    parser.add_argument("-o", "--output", metavar="OUTPUT.jsonl", default="-",
                        help="fit results to write (default: standard output)")
    parser.add_argument("--mode", choices=("video", "image"), default="video",
                        help="video (default): each frame starts from the previous one; image: every frame on "
                             "its own")
    add_config_args(parser, source=False)
    parser.set_defaults(func=run)


_err = error_printer("posed fit")


def run(args: argparse.Namespace) -> int:
    from posed.camera_model import Intrinsics
    from posed.fitting import CalibrationError, FitResult, Fitter
    from posed.landmarks import (
        RecordingError,
        RecordingProblem,
        RecordingSides,
        dumps,
        iter_recording,
    )

    config = config_from_args(args)
    cfg = config.fitting
    try:
        header, frames = iter_recording(args.input)
    except RecordingError as exc:
        _err(str(exc))
        return 2
    if cfg.calibration:                     # bounded first: a huge file or /dev/zero is not read whole
        from posed.daemon.preflight import calibration_problems

        for problem in calibration_problems(cfg.calibration):
            _err(problem)
            return 2
    try:
        fitter = Fitter(cfg)
    except CalibrationError as exc:
        _err(f"{exc} (fitting.calibration in the config)")
        return 2
    from posed.commands.warmup import warm_fitter

    warm_fitter(fitter, _err)        # compile before frame 0: its fit_ms must be the fit alone
    # a recording without the camera's intrinsics: the daemon's assumed lens (daemon.stages.fit)
    intrinsics = header.camera or Intrinsics.assume(config.falls.camera_hfov_deg, *header.image_size)
    out = sys.stdout if args.output == "-" else None
    if out is None:
        try:
            Path(args.output).parent.mkdir(parents=True, exist_ok=True)
            out = open(args.output, "w", encoding="utf-8")
        except OSError as exc:
            _err(f"{args.output}: cannot write: {exc.strerror}")
            return 2
    # left and right put back where the recording's extractor flipped them (landmarks.sides), unless the
    # recording says its landmark stage did that already
    sides = RecordingSides() if RecordingSides.needed(header, config.landmarks.keep_sides) else None
    # which way is down: a line's own gravity or depth floor, else the configured mount's when trusted
    # (daemon.stages.fit)
    from posed.daemon.stages.fit import frame_gravity, mount_gravity

    mount = mount_gravity(config.falls)
    skipped = fitted = ok = 0
    try:
        for item in frames:
            if isinstance(item, RecordingProblem):
                print(str(item), file=sys.stderr, flush=True)
                skipped += 1
                continue
            if sides is not None:
                item = sides(item)
            result = fitter.fit(item.landmarks, item.seq, item.t, header.image_size, mode=args.mode,
                                intrinsics=intrinsics, depth_m=item.depth_m, world=item.world,
                                gravity=frame_gravity(item, mount, config.falls.imu_gravity,
                                                      config.falls.floor_from_depth))
            try:
                line = dumps(result.to_json())
            except ValueError as exc:  # a non-finite number must never reach the output
                line = dumps(FitResult.failure(item.seq, item.t, f"result not representable as JSON: {exc}").to_json())
            out.write(line + "\n")
            fitted += 1
            ok += result.ok
    finally:
        if out is not sys.stdout:
            out.close()
        else:
            out.flush()
    swapped = 0 if sides is None else sides.frames_put_back
    _err(f"{fitted} frame(s) fitted ({ok} ok, {fitted - ok} not ok), {skipped} line(s) skipped"
         + (f"; left and right put back on {swapped} (landmarks.sides)" if swapped else ""))
    return 1 if skipped else 0
