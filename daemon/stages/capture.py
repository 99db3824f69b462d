"""Capture stage: camera or recording -> shared-memory ring -> ``frames`` mailbox (a FrameRef).

* Frames come from ``hal.open_source(config.source)``; the capture timestamp is the frame's ``t``
  (monotonic clock), and it travels with the frame to the publisher. Reading starts once every stage is
  ready (the supervisor's ``go``), so warm-up neither drops frames nor delays a replay's first ones.
* ``pipeline.target_fps`` thins the camera's rate: a frame is taken when at least 0.75 of the target period
  has passed since the last one taken (the others count as ``skipped``, not dropped).
* Live cameras and paced replays never wait: a FrameRef the landmark stage has not taken yet is replaced
  (a drop; the newest frame wins). An unpaced file replay (``source.realtime: false``) is lossless instead:
  every stage waits until the next one has taken its previous message, so the pipeline runs at the pace
  of its slowest stage and a benchmark measures throughput without drops.
* A disconnected or failing camera is closed and opened again with backoff (camera state ``lost``); a
  recording that ended leaves the stage idle (``ended``). A missing file or an unsupported source is fatal.
* A bad frame (one that does not decode, or one larger than a ring slot: a 10000x10000 image in a folder) is
  skipped and counted (``bad_frames`` in the status), logged with a rate limit (``frame_skipped``, with the
  fix), never fatal; the source reads on with the next frame. Image files are measured on their header, so
  an oversized one is never decoded.

``run_recording`` replaces capture *and* landmarks for a ``*.landmarks.jsonl`` source: it reads the
recording (``landmarks.recording``) and sends LandmarkMsg straight to the fitting stage, with capture
timestamps on the recording's time line from the start of the replay (like hal's replays); a frame's
``depth_m`` and ``gravity``, when the recording has them, travel on with the frame as the landmark stage's
would.

For unpaced replays the capture timestamps follow the recording, not the wall clock, so the FrameRef also
carries ``t_origin`` (when the frame was read), from which latency is measured.
"""

from __future__ import annotations

from dataclasses import replace

from posed.daemon import clock
from posed.daemon.messages import LandmarkMsg, origin
from posed.daemon.proc.ring import FrameTooLarge, too_large_fix
from posed.daemon.proc.throttle import Throttle
from posed.daemon.stages.base import StageRuntime, sleep_until

REOPEN_BACKOFF_S = (0.5, 1.0, 2.0, 5.0)


class _Thinner:
    """Takes frames at no more than ``target_fps`` (by capture time)."""

    def __init__(self, target_fps: float) -> None:
        self.min_gap = 0.75 / target_fps
        self.last: float | None = None

    def take(self, t: float) -> bool:
        if self.last is not None and self.last <= t < self.last + self.min_gap:
            return False
        self.last = t
        return True


def run(rt: StageRuntime) -> None:
    from posed import hal
    from posed.hal import (
        EndOfStream,
        SourceCorrupt,
        SourceError,
        SourceNotFound,
        SourceTimeout,
        SourceUnsupported,
    )

    src_cfg = rt.config.source
    paced = not (src_cfg.type == "file" and not src_cfg.realtime)
    thinner = _Thinner(rt.config.pipeline.target_fps)
    source = None
    failures = 0
    reported_ready = False
    throttle = Throttle()
    rt.row.set_camera("opening")
    try:
        while True:
            rt.beat()
            rt.check_stop()
            if source is None:
                try:
                    source = hal.open_source(src_cfg)
                    source.open()
                except SourceUnsupported as exc:
                    rt.fatal(str(exc), fix="check the source section (source.type, source.path, source.device)")
                except SourceError as exc:
                    if isinstance(exc, SourceNotFound) and src_cfg.type == "file":
                        rt.fatal(str(exc), fix="check source.path (or --source file:PATH)")
                    source = _failed_open(rt, source, exc, failures)
                    failures += 1
                    if not reported_ready:
                        reported_ready = True
                        rt.ready()
                    continue
                failures = 0
                source.max_pixels = rt.ring.spec.capacity_px
                rt.row.set_camera("open")
                rt.report(camera=_info(source))
                rt.log.info("camera_open", **_info(source))
                if not reported_ready:
                    reported_ready = True
                    rt.ready()
                rt.wait_go()
            try:
                frame = source.read(src_cfg.read_timeout_s)
                t_origin = None if paced else clock.now()    # unpaced: latency counts from the read
            except SourceTimeout:
                rt.error()
                continue
            except SourceCorrupt as exc:
                _bad_frame(rt, throttle, str(exc), exc.pixels)
                continue
            except EndOfStream:
                rt.row.set_camera("ended")
                rt.report(camera={"state": "ended"})
                rt.log.info("recording_ended", frames=int(rt.row.get("frames")))
                _close(source)
                source = None
                while True:
                    sleep_until(clock.now() + 0.2, rt)
            except SourceError as exc:
                rt.row.set_camera("lost")
                rt.report(camera={"state": "lost", "error": str(exc)})
                rt.log.warning("camera_lost", error=str(exc))
                _close(source)
                source = None
                continue
            if not thinner.take(frame.t):
                rt.skip()
                continue
            if not paced:
                rt.wait_taken()
            with rt.step():
                t0 = clock.now()
                try:
                    ref = rt.ring.write(frame.image, frame.seq, frame.t, frame.depth,
                                        float(getattr(frame, "depth_scale", 0.0) or 0.0),
                                        getattr(frame, "intrinsics", None), t_origin=t_origin,
                                        gravity=getattr(frame, "gravity", None))
                except FrameTooLarge as exc:
                    ref = None
                    _bad_frame(rt, throttle, str(exc), None)
                if ref is not None:
                    rt.send(ref)
            if ref is not None:
                rt.done(clock.now() - t0, origin(ref))
    finally:
        _close(source)
        rt.row.set_camera("none")


def _bad_frame(rt: StageRuntime, throttle: Throttle, error: str, pixels: int | None) -> None:
    """Skip and count a frame that cannot be used; log it (at most a few lines a minute)."""
    rt.bad_frame()
    suppressed = throttle.allow("bad_frame")
    if suppressed is not None:
        fix = too_large_fix(pixels) if pixels else "replace or delete the file"
        rt.log.warning("frame_skipped", error=error, fix=fix, bad_frames=int(rt.row.get("bad_frames")),
                       suppressed=suppressed)


def _failed_open(rt: StageRuntime, source, exc: Exception, failures: int):
    rt.row.set_camera("lost")
    wait = REOPEN_BACKOFF_S[min(failures, len(REOPEN_BACKOFF_S) - 1)]
    if failures == 0 or failures % 20 == 0:
        rt.log.warning("camera_unavailable", error=str(exc), retry_in_s=wait, attempts=failures + 1)
    rt.report(camera={"state": "lost", "error": str(exc)})
    _close(source)
    sleep_until(clock.now() + wait, rt)
    return None


def _info(source) -> dict:
    info = getattr(source, "info", None) or {}
    return {k: v for k, v in dict(info).items() if isinstance(v, (str, int, float, bool)) or v is None}


def _close(source) -> None:
    if source is None:
        return
    try:
        source.close()
    except Exception:  # closing a broken camera must not hide why we are closing
        pass


def run_recording(rt: StageRuntime) -> None:
    """Replay a ``*.landmarks.jsonl`` recording as the landmark stage's output."""
    from posed.landmarks import RecordingError, RecordingProblem, iter_recording

    src = rt.config.source
    thinner = _Thinner(rt.config.pipeline.target_fps)
    problems = 0
    first = True
    while True:
        try:
            header, stream = iter_recording(src.path)
        except RecordingError as exc:
            rt.fatal(str(exc), fix="check source.path (or --source file:PATH.landmarks.jsonl)")
        if first:
            rt.row.set_camera("open")
            info = {"kind": "landmark recording", "fps": header.fps,
                    "image_size": list(header.image_size)}
            rt.report(camera=info)
            rt.log.info("camera_open", **info)
            rt.ready()
            rt.wait_go()
            first = False
        intrinsics = header.camera
        t_start = clock.now()
        t_first: float | None = None
        for item in stream:
            rt.beat()
            rt.check_stop()
            if isinstance(item, RecordingProblem):
                problems += 1
                rt.error()
                if problems <= 3:
                    rt.log.warning("recording_problem", problem=str(item))
                continue
            if t_first is None:
                t_first = item.t
            if src.realtime:
                sleep_until(t_start + (item.t - t_first), rt, slice_s=0.05)
            if not thinner.take(t_start + (item.t - t_first)):
                rt.skip()
                continue
            if not src.realtime:
                rt.wait_taken()
            with rt.step():
                t_in = clock.now()
                t_capture = t_start + (item.t - t_first)      # the recording's time line
                frame = replace(item, t=t_capture)   # depth_m, gravity and unknown fields travel on
                msg = LandmarkMsg(frame, t_capture, tuple(header.image_size), intrinsics, (),
                                  None if src.realtime else t_in)
                rt.send(msg)
            rt.done(clock.now() - t_in, origin(msg))
        if not src.loop:
            break
        thinner.last = None
    rt.row.set_camera("ended")
    rt.report(camera={"state": "ended"})
    rt.log.info("recording_ended", frames=int(rt.row.get("frames")))
    while True:
        sleep_until(clock.now() + 0.2, rt)
