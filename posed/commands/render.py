"""``posed render INPUT -o OUT.webm``: the video with what posed found drawn on it (viz.render).

INPUT is a video (the landmark stage and the fit run here, in video mode, as the daemon runs them: with
``landmarks.max_people`` > 1 every person is followed, fitted and fall-checked, each drawn with their track id;
the angles and the fall state shown are the frame's own person's, another person's fall event is named) or a
landmark recording (``.landmarks.jsonl``) with its fit (``--fit FIT.jsonl``, from ``posed fit``) and, when
there is one, the source video (``--video``; otherwise the drawing is on a grey background). The fall
detector runs on the fits when ``falls.enabled``. Camera intrinsics: the recording's header, else the
config's ``source.fx``.. (as the daemon), else ``--hfov`` when given (the camera's own lens, as if measured);
without any a video is fitted as the daemon fits it, through the lens of ``falls.camera_hfov_deg`` assumed (no
``root_cam_m``: the model is drawn scaled to the landmarks).

Exit status: 0 written, 1 written but some frames or lines were unreadable, 2 nothing written, 74 the disk
filled up while writing (the partial file is removed; the message names the folder).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

from posed.commands import add_config_args, config_from_args, error_printer, read_jsonl

VIDEO_SUFFIXES = {".mp4", ".avi", ".mov", ".mkv", ".webm", ".m4v", ".mpg", ".mpeg"}


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("render", help="draw the landmarks, the fitted skeleton, joint angles and the fall "
                                           "state over a video (with a side view)")
    parser.add_argument("input", metavar="INPUT", help="a video, or a .landmarks.jsonl recording (then --fit)")
    parser.add_argument("-o", "--output", required=True, metavar="OUT.webm",
                        help="video to write: .webm (VP8, plays in browsers), .mp4 (H.264, needs ffmpeg) or .avi")
    parser.add_argument("--fit", metavar="FIT.jsonl", help="the fit of a landmark recording (posed fit output)")
    parser.add_argument("--video", metavar="VIDEO", help="the source video of a landmark recording")
    parser.add_argument("--hfov", type=_hfov, metavar="DEG",
                        help="the camera's horizontal field of view when the input has no intrinsics (taken "
                             "as its own lens: the fit of a video places the person in metres; without it the "
                             "lens of falls.camera_hfov_deg is assumed, as the daemon does; a fit file keeps "
                             "the model it was made with)")
    parser.add_argument("--camera-height", type=float, default=0.0, metavar="M",
                        help="the camera's height above the floor, for the side view's floor with a "
                             "perspective fit (default: the floor is estimated below the lowest joint)")
    parser.add_argument("--max-height", type=int, default=720, metavar="PX",
                        help="scale the output down to at most this height (default 720; 0 = the input's "
                             "size): encoding dominates the time on large frames")
    parser.add_argument("--no-falls", action="store_true", help="do not run the fall detector")
    parser.add_argument("--progress", action="store_true",
                        help="show a progress bar on stderr (default: only when stderr is a terminal)")
    add_config_args(parser, source=False)
    parser.set_defaults(func=run)


_err = error_printer("posed render")


def _hfov(text: str) -> float:
    """--hfov: a horizontal field of view in degrees, above 0 and below 180."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of degrees") from None
    if not 0.0 < value < 180.0:
        raise argparse.ArgumentTypeError(f"{text} degrees is not a field of view; give one above 0 and below 180 "
                                         "(a webcam: about 60 to 90)")
    return value


def _holds_fit_results(path: Path) -> bool:
    """Whether the file's first line is a ``posed fit`` result (seq, ok, no format header) rather than the
    header of a landmark recording."""
    try:
        with path.open("rb") as fh:
            first = fh.readline(1 << 20)
        obj = json.loads(first)
    except (OSError, ValueError):
        return False
    return isinstance(obj, dict) and "format" not in obj and "seq" in obj and "ok" in obj


def _intrinsics(header_camera, image_size, config, hfov):
    from posed.camera_model import Intrinsics

    if header_camera is not None:
        return header_camera
    src = config.source
    w, h = int(image_size[0]), int(image_size[1])
    if src.fx > 0:
        return Intrinsics(src.fx, src.fy or src.fx, src.cx or w / 2.0, src.cy or h / 2.0, src.width,
                          src.height).scaled(w, h)
    if hfov:
        return Intrinsics.from_hfov(hfov, w, h)
    return None


def _fit_video(args, config, progress_on):
    """Landmarks + fit over a video (video mode, like the daemon): (source info, intrinsics, items, problems)."""
    from dataclasses import replace

    from posed.commands.landmarks import open_input
    from posed.daemon.stages.fit import people_fit
    from posed.fitting import Fitter
    from posed.landmarks import MultiPoseLandmarker, PoseLandmarker
    from posed.viz.video import Progress

    source = open_input(Path(args.input), None, config.source.fps)
    intrinsics = _intrinsics(source.camera, source.image_size, config, args.hfov)
    lm_config = replace(config.landmarks, tracking=True)
    landmarker = MultiPoseLandmarker(lm_config) if lm_config.max_people > 1 else PoseLandmarker(lm_config)
    # the fitting stage's own logic: a fitter per person, the assumed lens when the source has none
    stream = people_fit(lambda: Fitter(config.fitting), config)
    items, problems = [], 0
    count = _frame_count(args.input)
    bar = Progress(count, "landmarks + fit", progress_on)
    for frame in source.frames:
        if frame.image is None:
            _err(frame.problem)
            problems += 1
            continue
        lf = landmarker.process(frame.image, frame.t, frame.seq)
        result, others = stream.fit(lf, lf.t, source.image_size, intrinsics)
        items.append((lf.seq, lf.t, lf.landmarks, result, _others(lf, others)))
        bar.step()
    bar.finish()
    return source.image_size, source.fps, intrinsics, items, problems


def _others(frame, others) -> tuple:
    """The frame's other people as the renderer draws them: (track id, landmarks, fit) each."""
    marks = {p.id: p.landmarks for p in (frame.people or ())}
    return tuple((r.extra.get("person"), marks.get(r.extra.get("person")), r) for r in others)


def _frame_count(path) -> int | None:
    import cv2

    cap = cv2.VideoCapture(str(path))
    n = int(cap.get(cv2.CAP_PROP_FRAME_COUNT) or 0)
    cap.release()
    return n or None


def _read_fit(path: str):
    """The fit results of a ``posed fit`` output by (seq, person) (person None: a frame of one person), and
    how many lines could not be read."""
    from posed.fitting import FitResult

    results, problems = read_jsonl(path, FitResult.from_json)
    return {(r.seq, r.extra.get("person")): r for r in results}, problems


def _from_recording(args, config):
    from posed.landmarks import RecordingProblem, RecordingSides, iter_recording

    header, frames = iter_recording(args.input)   # RecordingError: caller reports
    fits, problems = _read_fit(args.fit)
    # the labels drawn are those the fit was given: posed fit put back where the extractor flipped them
    sides = RecordingSides() if RecordingSides.needed(header, config.landmarks.keep_sides) else None
    items = []
    for f in frames:
        if isinstance(f, RecordingProblem):
            print(str(f), file=sys.stderr)
            problems += 1
            continue
        if sides is not None:
            f = sides(f)
        # the frame's own person: the one whose landmarks are the frame's (posed fit writes a line per person)
        mine = f.own_person()
        own = fits.get((f.seq, mine)) or fits.get((f.seq, None))
        items.append((f.seq, f.t, f.landmarks, own,
                      tuple((p.id, p.landmarks, fits.get((f.seq, p.id))) for p in (f.people or ()) if p.id != mine)))
    intrinsics = _intrinsics(header.camera, header.image_size, config, args.hfov)
    return header.image_size, header.fps, intrinsics, items, problems


def run(args: argparse.Namespace) -> int:
    import cv2

    from posed.commands.landmarks import InputError
    from posed.landmarks import ModelMissingError, RecordingError
    from posed.viz.render import ClipRenderer, FrameInput
    from posed.viz.video import DiskFullError, Progress, VideoError, VideoOut

    config = config_from_args(args)
    progress_on = args.progress or sys.stderr.isatty()
    path = Path(args.input)
    is_recording = path.name.endswith(".jsonl")
    if not path.exists():
        _err(f"{path}: no such file")
        return 2
    try:
        if is_recording:
            if _holds_fit_results(path):
                _err(f"{path} holds fit results; give the landmark recording it came from with --fit {path} "
                     f"(posed render REC.landmarks.jsonl --fit {path} -o {args.output})")
                return 2
            if not args.fit:
                _err(f"{path} is a landmark recording: give its fit with --fit FIT.jsonl "
                     f"(posed fit {path} -o FIT.jsonl)")
                return 2
            image_size, fps, intrinsics, items, problems = _from_recording(args, config)
            video_path = args.video
        else:
            if args.fit:
                _err("--fit goes with a landmark recording; a video is fitted here")
                return 2
            image_size, fps, intrinsics, items, problems = _fit_video(args, config, progress_on)
            video_path = str(path)
    except (InputError, RecordingError, ModelMissingError, OSError) as exc:
        _err(str(exc))
        return 2
    if not items:
        _err("the input holds no frame to draw")
        return 2
    states = _falls(items, image_size, intrinsics, config) if config.falls.enabled and not args.no_falls \
        else [(None, None)] * len(items)
    renderer = ClipRenderer(image_size, intrinsics, [it[3] for it in items],
                             camera_height_m=args.camera_height)
    cap = None
    if video_path:
        cap = cv2.VideoCapture(video_path)
        if not cap.isOpened():
            _err(f"{video_path}: cannot open the video (drawing on a grey background instead)")
            cap, problems = None, problems + 1
    bar = Progress(len(items), "render", progress_on)
    w, h = renderer.size
    k = args.max_height / h if 0 < args.max_height < h else 1.0
    size = (int(round(w * k)), int(round(h * k)))
    try:
        with VideoOut(args.output, fps, size) as out:
            next_index = 0
            image = None
            for (seq, t, lm, result, others), (state, event) in zip(items, states, strict=True):
                if cap is not None:
                    while next_index <= seq:           # the video frame of this seq (seq = frame index)
                        ok, image = cap.read()
                        next_index += 1
                        if not ok:
                            image = None
                            break
                    if image is not None and (image.shape[1], image.shape[0]) != tuple(image_size):
                        image = cv2.resize(image, tuple(int(v) for v in image_size))
                person = None if result is None else result.extra.get("person")
                frame = renderer.frame(image, FrameInput(seq, t, lm, result, state, event, person, others))
                if k != 1.0:
                    frame = cv2.resize(frame, size, interpolation=cv2.INTER_AREA)
                out.write(frame)
                bar.step()
    except DiskFullError as exc:
        _err(str(exc))
        return os.EX_IOERR
    except VideoError as exc:
        _err(str(exc))
        return 2
    finally:
        if cap is not None:
            cap.release()
    bar.finish()
    how = "perspective reprojection" if renderer.absolute else "laid on the landmarks (scale and offset)"
    _err(f"{len(items)} frames -> {args.output} ({out.size[0]}x{out.size[1]}, {fps:g} fps, "
         f"skeleton: {how})")
    return 1 if problems else 0


def _falls(items, image_size, intrinsics, config):
    """The fall detector's state after each frame (the shown person's) and the last event message's state
    (``person N: state`` when it was another person's), a detector per person as the daemon runs them."""
    from posed.falls import FallDetector
    from posed.falls.people import PeopleFalls

    watch = PeopleFalls(FallDetector(config.falls, config.robot_id))
    out, last = [], None
    for seq, t, lm, result, others in items:
        if result is None:                        # a frame the fit file does not have: nothing to judge
            out.append((watch.main.state, last))
            continue
        people = [(result.extra.get("person"), result, lm)]
        people += [(pid, r, marks) for pid, marks, r in others if r is not None]
        for ev in watch.update(people, t, seq, image_size, intrinsics):
            whose = ev.extra.get("person")
            last = ev.state if whose is None or whose == people[0][0] else f"person {whose}: {ev.state}"
        out.append((watch.main.state, last))
    return out
