"""``posed fit INPUT.landmarks.jsonl [-o OUTPUT.jsonl] [--mode video|image] [--config FILE]``: the 3D fit alone.

Reads a landmark recording (interfaces.md section 1) and writes one fit result per frame as JSON Lines
(interfaces.md section 2; standard output without ``-o``). Frames without a person, with missing, NaN or
low-visibility landmarks get ``"ok": false`` and a reason; a line that cannot be read is reported on stderr as
``FILE:LINE: message`` and skipped. The recording header's ``camera`` intrinsics, when present, select the
perspective model (``fitting.projection: auto``); without them the fit projects, as the daemon's does, through
the lens of ``falls.camera_hfov_deg`` assumed (the results say ``"lens": "assumed"`` and carry no
``root_cam_m``; ``fitting.projection: orthographic`` gives the paper's orthographic fit).

An output that is the input (or a link to it) is refused before anything is written; an image or video
given as the input is named as such (``posed landmarks`` makes a recording of it).

Exit status: 0 every line was read, 1 some lines were skipped, 2 the recording cannot be read at all (or the
output is the input, or cannot be created), 74 writing the results failed (a full disk: the partial file is
removed).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace

from posed.commands import add_config_args, config_from_args, error_printer
from posed.commands._paths import Output, OutputError, config_inputs, refuse_same_file, sniff


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

    refused = refuse_same_file("posed fit", args.output,
                               [("recording", args.input), *config_inputs(args)])
    if refused is not None:
        return refused
    config = config_from_args(args)
    cfg = config.fitting
    refused = refuse_same_file("posed fit", args.output, [("calibration file", cfg.calibration or None)])
    if refused is not None:
        return refused
    wrong = _not_a_recording(args.input)
    if wrong:
        _err(wrong)
        return 2
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
    out = Output("posed fit", args.output)
    try:
        out.open(mkdir=True)
    except OSError as exc:
        return out.open_failed(exc)
    # left and right put back where the recording's extractor flipped them (landmarks.sides), unless the
    # recording says its landmark stage did that already
    sides = RecordingSides() if RecordingSides.needed(header, config.landmarks.keep_sides) else None
    # which way is down: a line's own gravity or depth floor, else the configured mount's when trusted
    # (daemon.stages.fit)
    from posed.daemon.stages.fit import PersonFitters, frame_gravity, mount_gravity

    mount = mount_gravity(config.falls)
    people = PersonFitters(fitter, lambda: Fitter(cfg))     # each person followed by a fitter of their own
    ids: set[int] = set()
    skipped = fitted = ok = 0
    last_t: float | None = None
    backwards: list[int] = []
    try:
        for item in frames:
            if isinstance(item, RecordingProblem):
                print(str(item), file=sys.stderr, flush=True)
                skipped += 1
                continue
            if sides is not None:
                item = sides(item)
            if last_t is not None and item.t < last_t:
                backwards.append(item.seq)   # the fit starts over there (fitting.Fitter: image mode)
            last_t = item.t
            gravity = frame_gravity(item, mount, config.falls.imu_gravity, config.falls.floor_from_depth)
            for person, own, person_fitter in _persons(item, people, ids):
                result = person_fitter.fit(
                    own.landmarks, item.seq, item.t, header.image_size, mode=args.mode, intrinsics=intrinsics,
                    depth_m=own.depth_m, world=own.world, gravity=gravity)
                if person is not None:
                    result = replace(result, extra={**result.extra, "person": person})
                try:
                    line = dumps(result.to_json())
                except ValueError as exc:  # a non-finite number must never reach the output
                    bad = FitResult.failure(item.seq, item.t, f"result not representable as JSON: {exc}")
                    line = dumps((replace(bad, extra={"person": person}) if person is not None else bad).to_json())
                out.write(line + "\n")
                fitted += 1
                ok += result.ok
        out.close()
    except OutputError as exc:
        return out.failed(exc.exc)
    finally:
        out.discard()
    if backwards:
        _err(f"{len(backwards)} frame(s) with a time `t` earlier than the frame before (first: seq {backwards[0]}): "
             "the recording's clock went backwards there; each such frame was fitted on its own (image mode), "
             "not from the one before")
    swapped = 0 if sides is None else sides.frames_put_back
    several = f" of {len(ids)} people (one line per person per frame, each with its `person`)" \
        if len(ids) > 1 else ""
    _err(f"{fitted} {'fit(s)' if several else 'frame(s) fitted'}{several} ({ok} ok, {fitted - ok} not ok), "
         f"{skipped} line(s) skipped" + (f"; left and right put back on {swapped} (landmarks.sides)" if swapped else ""))
    return 1 if skipped else 0


def _persons(item, people, ids: set[int]) -> list:
    """(track id or None, what to fit: landmarks, world, depth_m, the fitter) for each person of ``item``: a
    frame without ``people`` is its one person, fitted by the first fitter exactly as before (no ``person`` in
    the result); a frame with ``people`` gives each person, the frame's own first (daemon.stages.fit's
    ``PersonFitters``, as the daemon's fitting stage assigns them)."""
    if not item.people:
        return [(None, item, people.main)]
    primary = people.own_person(item, item.t)
    out = [(p.id, p, people.main if p.id == primary else people.of(p.id, item.t))
           for p in sorted(item.people, key=lambda p: p.id != primary)]
    people.forget(item.t)
    ids.update(p.id for p in item.people)
    return out


def _not_a_recording(path: str) -> str:
    """Why ``path`` is plainly not a landmark recording (an image, a video, a database), or ""."""
    kind, what = sniff(path)
    if kind in ("image", "video"):
        return (f"{path} looks like {'an' if kind == 'image' else 'a'} {kind} ({what}), not a landmark recording: "
                f"run `posed landmarks {path} -o REC.landmarks.jsonl` first, then `posed fit REC.landmarks.jsonl`")
    if kind == "database":
        return (f"{path} is an SQLite file (a RealSense .db3 recording, or a posed database), not a landmark "
                f"recording: for a RealSense recording run `posed landmarks {path} -o REC.landmarks.jsonl` first")
    return ""
