"""``posed falls RECORDING.landmarks.jsonl [--config FILE] [--set K=V]``: the fall detector offline.

The frames the capture stage would take (no more than ``pipeline.target_fps`` by capture time, as
``posed run --source file:REC`` replays it), the fit (video mode, reset as the fitting stage resets it, a fitter
per person of a recording with ``people``: :class:`daemon.stages.fit.PeopleFit`) and the fall detector
(:class:`daemon.stages.fall_watch.FallWatch`, as the publisher stage runs it: a detector per person) on every
frame of a landmark recording, frames without a person included. Each event message is printed as one JSON line,
exactly the payload ``posed/ROBOT/events/fall`` would carry (:func:`event_payload`: the publisher's
``stamp_event`` and ``event_message``, ``wall_time`` as the journal fills it, the bus's ``dumps``; the unix
times count the recording's t from when the command started). The recording's time line is the capture clock; the header's
``camera`` intrinsics go to the fit and the detector, as in ``posed run --source file:...``.

Exit status: 0 read whole, 1 some lines were skipped, 2 the recording cannot be read at all.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Iterable, Iterator

from posed.commands import add_config_args, config_from_args, error_printer


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("falls", help="run the fit and the fall detector on a landmark recording "
                                          "(one JSON line per fall-event message)")
    parser.add_argument("input", metavar="RECORDING.landmarks.jsonl", help="landmark recording to judge")
    parser.add_argument("--summary", action="store_true",
                        help="also print one line per message on stderr (state, time, confidence, features)")
    add_config_args(parser, source=False)
    parser.set_defaults(func=run)


_err = error_printer("posed falls")


def taken_frames(pipeline_config, frames: Iterable, period_s: float = 1.0 / 30.0) -> Iterator:
    """The frames the capture stage takes from a recording: on its capture clock (``hal.ReplayClock``: a
    repeated, backward or leaping timestamp is one frame period ``period_s`` after the frame before, as the
    daemon replays it), at most ``target_fps`` by capture time."""
    from dataclasses import replace

    from posed.daemon.stages.capture import _Thinner
    from posed.hal import ReplayClock

    thinner = _Thinner(pipeline_config.target_fps)
    line = ReplayClock()
    for frame in frames:
        t = line.map(frame.t, period_s)
        if t != frame.t:
            frame = replace(frame, t=t)
        if thinner.take(t):
            yield frame


def sides_kept(header, frames: Iterable, enabled: bool = True) -> Iterator:
    """The frames with left and right put back where the recording's extractor flipped them, as the daemon's
    recording replay does to the frames it takes (landmarks.RecordingSides): when ``enabled`` (the config's
    ``landmarks.keep_sides``) and the header does not say ``sides_kept``."""
    from posed.landmarks import RecordingSides

    return map(RecordingSides(), frames) if RecordingSides.needed(header, enabled) else iter(frames)


def fit_frames(cfg, header, frames: Iterable) -> Iterator[tuple[object, object, tuple]]:
    """(LandmarkFrame, FitResult, the other people's FitResults) per frame, fitted as the fitting stage fits
    them (:func:`daemon.stages.fit.people_fit`: a frame without ``people`` has no others; a recording
    without ``camera`` through the assumed lens of ``falls.camera_hfov_deg``). ``cfg``: the whole config."""
    from posed.daemon.stages.fit import people_fit
    from posed.fitting import Fitter

    people = people_fit(lambda: Fitter(cfg.fitting), cfg)
    for frame in frames:
        result, others = people.fit(frame, frame.t, tuple(header.image_size), header.camera)
        yield frame, result, others


def detect(cfg, header, fitted: Iterable[tuple], log=None) -> Iterator[tuple[object, object, list]]:
    """(frame, result, fall-event messages) per frame, through the publisher stage's FallWatch (a fall
    detector per person); ``fitted`` gives (frame, result) or (frame, result, the other people's results)."""
    from posed.daemon.messages import FitMsg
    from posed.daemon.stages.fall_watch import FallWatch

    if log is None:
        import structlog

        log = structlog.get_logger("posed.falls")
    watch = FallWatch.from_config(cfg.falls, cfg.robot_id, log)
    size = tuple(header.image_size)
    for frame, result, *others in fitted:
        msg = FitMsg(result, frame, frame.t, size, (), header.camera, others=others[0] if others else ())
        yield frame, result, watch.update(msg)


def event_payload(event, wall0: float | None = None) -> str:
    """The text the publisher stage puts on events/fall for ``event``: ``stamp_event`` (format, version, unix
    times), ``wall_time`` as the journal fills it, ``event_message``, the bus's ``dumps``. Offline the unix
    times map the recording's time line onto the wall clock with its t = 0 at ``wall0`` (default: now)."""
    from dataclasses import replace

    from posed.daemon.bus.payloads import dumps, event_message, stamp_event
    from posed.daemon.clock import iso

    wall0 = time.time() if wall0 is None else wall0

    def unix(t):
        return None if t is None else round(wall0 + t, 4)

    ev = stamp_event(event)
    extra = {**ev.extra, "time_unix": unix(ev.t_detect), "t_onset_unix": unix(ev.t_onset),
             "t_impact_unix": unix(ev.t_impact)}
    ev = replace(ev, extra=extra, wall_time=ev.wall_time or iso(wall0 + ev.t_detect))
    return dumps(event_message(ev.to_json()))


def run(args: argparse.Namespace) -> int:
    from posed.fitting import CalibrationError
    from posed.landmarks import RecordingError, RecordingProblem, RecordingSides, iter_recording

    cfg = config_from_args(args)
    try:
        header, stream = iter_recording(args.input)
    except (RecordingError, OSError) as exc:
        _err(str(exc))
        return 2
    sides = RecordingSides() if RecordingSides.needed(header, cfg.landmarks.keep_sides) else None
    skipped = read = 0

    def frames():
        nonlocal skipped, read
        for item in stream:
            if isinstance(item, RecordingProblem):
                print(str(item), file=sys.stderr, flush=True)
                skipped += 1
                continue
            read += 1
            yield item

    n = events = 0
    wall0 = time.time()
    try:
        period = 1.0 / (header.fps if header.fps and header.fps > 0 else cfg.source.fps)
        taken = taken_frames(cfg.pipeline, frames(), period)
        if sides is not None:      # left and right put back where the extractor flipped them (as posed fit)
            taken = map(sides, taken)
        for _frame, _result, messages in detect(cfg, header, fit_frames(cfg, header, taken)):
            n += 1
            for ev in messages:
                events += 1
                print(event_payload(ev, wall0), flush=True)
                if args.summary:
                    _err(f"{ev.state:10} t={ev.t_detect:.3f} s  confidence {ev.confidence:.2f}  "
                         f"{','.join(ev.features)}")
    except CalibrationError as exc:
        _err(f"{exc} (fitting.calibration in the config)")
        return 2
    judged = f"{n} frames" if n == read else (
        f"{n} of the recording's {read} frames judged (at most pipeline.target_fps = {cfg.pipeline.target_fps:g} "
        "a second of capture time, as the daemon's capture stage takes them; posed fit fits them all)")
    swapped = 0 if sides is None else sides.frames_put_back
    _err(f"{judged}, {events} event message(s), {skipped} line(s) skipped"
         + (f"; left and right put back on {swapped} (landmarks.sides)" if swapped else ""))
    return 1 if skipped else 0
