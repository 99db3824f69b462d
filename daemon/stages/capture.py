"""Capture stage: camera or recording -> shared-memory ring -> ``frames`` mailbox (a FrameRef).

* Frames come from ``hal.open_source(config.source)``; the capture timestamp is the frame's ``t``
  (monotonic clock), and it travels with the frame to the publisher. Reading starts once every stage is
  ready (the supervisor's ``go``), so warm-up neither drops frames nor delays a replay's first ones.
* ``pipeline.target_fps`` thins the camera's rate: a frame is taken when it is at most a quarter of the
  target period early for the next due time, due times a target period apart (the others count as
  ``skipped``, not dropped), so 30, 60 or 25 fps all give the target rate; a slower source gives every frame.
* Live cameras and paced replays never wait: a FrameRef the landmark stage has not taken yet is replaced
  (a drop; the newest frame wins). An unpaced file replay (``source.realtime: false``) is lossless instead:
  every stage waits until the next one has taken its previous message, so the pipeline runs at the pace
  of its slowest stage and a benchmark measures throughput without drops.
* A disconnected or failing camera is closed and opened again with backoff (camera state ``lost``); a
  recording that ended leaves the stage idle (``ended``). A missing file or an unsupported source is fatal.
* Any frame size: a frame with more pixels than a ring slot (``pipeline.frame_max_pixels``, the working size)
  is scaled down once, here, by the smallest whole factor that fits (``hal.scale_factor``: area interpolation,
  0.5 ms for 1920x1080); the FrameRef carries the factor and the source's own size, and the landmark stage
  reports landmarks in the source's pixels, so nothing downstream sees the scaling. ``camera`` in the status
  has the source's size and the working size (``working_width``, ``working_height``, ``scale``).
* A bad frame (one that does not decode, or an image above ``hal.MAX_DECODE_PIXELS``, 8K, which is never
  decoded) is skipped and counted (``bad_frames`` in the status), logged with a rate limit (``frame_skipped``,
  with the fix), never fatal; the source reads on with the next frame. The last problem (a bad frame, a read
  timeout, a clock jump) goes to the supervisor with its fix, which says ``blind`` with it when no frame
  reaches the landmark stage for a while.
* Night: a RealSense delivers its infrared image when the colour one is dark (``hal.night``); the frame's
  ``spectrum`` says which. ``camera`` in the status has ``spectrum`` (``colour`` or ``infrared``) and
  ``spectrum_since_unix`` (the capture time of the first frame in it), and each switch is logged once
  (``camera_dark``: "camera: dark, watching by infrared"; ``camera_light``: "camera: light again, colour").
* A recording is a recording, not a camera: its log line is ``recording_open`` (``camera_open`` for a
  camera) and the status' ``camera.kind`` says ``file``.
* Paused for privacy (:class:`daemon.stages.privacy_gate.PauseGate`: the publisher's orders, privacy.json at the
  start, the clock): a live camera is closed until the pause ends (its LED goes off), a recording's frames are
  read and discarded (its time line runs on); camera state ``paused``. Nothing reaches the next stage.

``run_recording`` replaces capture *and* landmarks for a ``*.landmarks.jsonl`` source: it reads the
recording (``landmarks.recording``) and sends LandmarkMsg straight to the fitting stage, with capture
timestamps on the recording's time line from the start of the replay (like hal's replays); a frame's
``depth_m`` and ``gravity``, when the recording has them, travel on with the frame as the landmark stage's
would.

For unpaced replays the capture timestamps follow the recording, not the wall clock, so the FrameRef also
carries ``t_origin`` (when the frame was read), from which latency is measured. A landmark recording's time
line goes through the same :class:`hal.ReplayClock` as hal's replays (a repeated, backward or leaping
timestamp is a clock jump: one frame period after the frame before), paced or not, and its ``seq`` continues
over the passes of a loop, as hal's do.
"""

from __future__ import annotations

from dataclasses import replace

from posed.daemon import clock
from posed.daemon.messages import LandmarkMsg, origin
from posed.daemon.proc.ring import FrameTooLarge, too_large_fix
from posed.daemon.proc.throttle import Throttle
from posed.daemon.stages.base import StageRuntime, sleep_until

REOPEN_BACKOFF_S = (0.5, 1.0, 2.0, 5.0)
UNEXPECTED_FILE_FAILURES = 50      # reads in a row of a recording that failed unexpectedly: it is unreadable


class _Thinner:
    """Takes frames at no more than ``target_fps`` (by capture time), on a schedule: the frames due every
    target period, each taken from a quarter of a period early (a camera's jitter), the schedule kept from
    due time to due time so that a 60 fps or 25 fps source gives the target rate on average (10 fps, not the
    12 or 12.5 that a minimum gap between frames gives). A source slower than the target gives every frame;
    a gap or a time line that went back starts the schedule again."""

    def __init__(self, target_fps: float) -> None:
        self.period = 1.0 / target_fps
        self.min_gap = 0.75 * self.period
        self.last: float | None = None
        self.due: float | None = None

    def take(self, t: float) -> bool:
        if self.last is not None and self.last <= t < self.due - 0.25 * self.period:
            return False
        if self.due is None or t < (self.last or t) or t > self.due + self.period:
            self.due = t + self.period            # start (again): from this frame
        else:
            self.due += self.period
        self.last = t
        return True


def run(rt: StageRuntime) -> None:
    from posed import hal
    from posed.hal import (
        EndOfStream,
        SourceCorrupt,
        SourceDisconnected,
        SourceError,
        SourceNotFound,
        SourceTimeout,
        SourceUnsupported,
    )

    src_cfg = rt.config.source
    paced = not (src_cfg.type == "file" and not src_cfg.realtime)
    thinner = _Thinner(rt.config.pipeline.target_fps)
    slot_px = rt.ring.spec.capacity_px
    source = None
    failures = 0
    reported_ready = False
    throttle = Throttle()
    news = _News(rt)
    unplugged = False
    unexpected = 0                  # reads in a row that failed with something other than a SourceError
    gate = _gate(rt)                # a pause for privacy: a camera closed, a recording's frames discarded
    live = src_cfg.type != "file"
    was_paused = False
    rt.row.set_camera("opening")
    try:
        while True:
            rt.beat()
            rt.check_stop()
            paused = gate.paused()
            if paused != was_paused:
                was_paused = paused
                news.privacy(paused, gate.pause)
                if not paused and source is not None:
                    rt.row.set_camera("lost" if unplugged else "open")
            if paused and live:         # the camera is closed (its LED goes off) until the pause ends
                if source is not None:
                    _close(source)
                    source = None
                    unplugged = False
                rt.row.set_camera("paused")
                if not reported_ready:
                    reported_ready = True
                    rt.ready()
                sleep_until(clock.now() + 0.1, rt)
                continue
            if source is None:
                try:
                    source = hal.open_source(src_cfg)
                    source.open()
                except SourceUnsupported as exc:
                    rt.fatal(str(exc), fix="check the source section (source.type, source.path, source.device)")
                except SourceError as exc:
                    if isinstance(exc, (SourceNotFound, SourceCorrupt)) and src_cfg.type == "file":
                        rt.fatal(str(exc), fix="check source.path (or --source file:PATH); posed config check "
                                               "--source file:PATH probes it")
                    source = _failed_open(rt, source, exc, failures)
                    failures += 1
                    if not reported_ready:
                        reported_ready = True
                        rt.ready()
                    continue
                failures = 0
                source.max_pixels = max(slot_px, hal.MAX_DECODE_PIXELS)   # larger: never decoded
                rt.row.set_camera("paused" if paused else "open")
                news.opened(source)
                if not reported_ready:
                    reported_ready = True
                    rt.ready()
                rt.wait_go()
            try:
                frame = source.read(src_cfg.read_timeout_s)
                t_origin = None if paced else clock.now()    # unpaced: latency counts from the read
            except SourceTimeout as exc:
                rt.error()
                news.problem(str(exc), _timeout_fix(src_cfg))
                continue
            except SourceCorrupt as exc:
                _bad_frame(rt, throttle, news, str(exc), exc.pixels, source, getattr(exc, "fix", ""))
                continue
            except SourceDisconnected as exc:
                # the source reconnects by itself while it is read (hal/errors.py): keep reading it. Closing and
                # opening it again would start a recording over from its first frame
                if not unplugged:
                    unplugged = True
                    rt.row.set_camera("lost")
                    news.lost(str(exc))
                continue
            except EndOfStream:
                rt.row.set_camera("ended")
                news.ended(source)
                _close(source)
                source = None
                while True:
                    sleep_until(clock.now() + 0.2, rt)
            except SourceError as exc:
                rt.row.set_camera("lost")
                news.lost(str(exc))
                _close(source)
                source = None
                continue
            except Exception as exc:  # a source's own bug or a driver's surprise: never the end of the stage
                # (the supervisor would restart it until it gave up, exit 70, and a camera would stay unwatched)
                unexpected += 1
                error = f"{getattr(source, 'name', 'the source')}: reading a frame failed ({type(exc).__name__}: " \
                        f"{exc})"
                if unexpected <= 3 or unexpected % 100 == 0:
                    rt.log.error("capture_failed", error=error, failures=unexpected)
                if src_cfg.type == "file" and unexpected >= UNEXPECTED_FILE_FAILURES:
                    rt.fatal(f"{error}, {unexpected} times in a row", fix="check the file with posed config check "
                             "--source file:PATH, re-encode or re-record it")
                if src_cfg.type == "file":       # a recording goes on after the frame (opened again, it would
                    _bad_frame(rt, throttle, news, error, None, source)    # start over from its first frame)
                    continue
                rt.row.set_camera("lost")        # a camera is closed and opened again, with backoff
                news.lost(error)
                _close(source)
                source = None
                sleep_until(clock.now() + REOPEN_BACKOFF_S[min(unexpected - 1, len(REOPEN_BACKOFF_S) - 1)], rt)
                continue
            unexpected = 0
            if unplugged:
                unplugged = False
                rt.row.set_camera("paused" if paused else "open")
                news.back(source)
            if paused:                  # a recording runs on, unseen: its frames are read and discarded
                rt.row.set_camera("paused")
                continue
            news.frame(source, frame)
            if not thinner.take(frame.t):
                rt.skip()
                continue
            if not paced:
                rt.wait_taken()
            with rt.step():
                t0 = clock.now()
                try:
                    ref = _to_ring(rt, frame, slot_px, t_origin)
                except FrameTooLarge as exc:        # cannot happen after the scaling; kept as a guard
                    ref = None
                    _bad_frame(rt, throttle, news, str(exc), None, source)
                if ref is not None:
                    rt.send(ref)
            if ref is not None:
                rt.done(clock.now() - t0, origin(ref))
    finally:
        _close(source)
        rt.row.set_camera("none")


def _gate(rt: StageRuntime):
    """The pause for privacy as this stage sees it: the publisher's orders (the ``privacy`` mailbox), the state
    dir's privacy.json at the start, and the clock (:class:`daemon.stages.privacy_gate.PauseGate`)."""
    from posed.daemon.config import paths
    from posed.daemon.stages.privacy_gate import PauseGate

    box = rt.control.mailboxes.get("privacy")
    return PauseGate(box, paths.state_dir(rt.config.pipeline), rt.log)


def _to_ring(rt: StageRuntime, frame, slot_px: int, t_origin: float | None):
    """Write ``frame`` to the ring, scaled down by a whole factor first when it has more pixels than a slot."""
    from posed.hal import downscale, downscale_depth, scale_factor

    image, depth = frame.image, frame.depth
    h, w = image.shape[:2]
    k = scale_factor(w, h, slot_px)
    if k > 1:
        image = downscale(image, k)
        depth = None if depth is None else downscale_depth(depth, k)
    return rt.ring.write(image, frame.seq, frame.t, depth, float(getattr(frame, "depth_scale", 0.0) or 0.0),
                         getattr(frame, "intrinsics", None), t_origin=t_origin,
                         gravity=getattr(frame, "gravity", None), scale=k,
                         source_size=(w, h) if k > 1 else None)


class _News:
    """What the capture stage tells the supervisor (``report(camera=..., problem=...)``) and the log: the source
    it opened (a camera or a recording), its size and the working size once the first frame came, clock jumps,
    and the last problem (with its fix) at most twice a second. Every report carries the camera info, so a
    problem never hides it (the report mailbox keeps only the latest message)."""

    def __init__(self, rt: StageRuntime) -> None:
        self.rt = rt
        self.camera: dict = {}
        self.size: tuple[int, int] | None = None
        self.next_refresh = 0.0
        self.next_problem = 0.0
        self.jumps = 0
        self.last_problem: dict | None = None
        self.spectrum: dict = {}                    # spectrum and spectrum_since_unix, once a frame came

    def _send(self) -> None:
        extra = {"problem": self.last_problem} if self.last_problem else {}
        self.rt.report(camera=dict(self.camera), **extra)

    def opened(self, source) -> None:
        info = _info(source)
        paused = {k: v for k, v in self.camera.items() if k == "paused_until_unix"}    # opened during a pause
        self.camera = {**info, "kind": _kind(info), **paused, **self.spectrum}
        self.size = None
        event = "recording_open" if self.camera["kind"] == "file" else "camera_open"
        self.rt.log.info(event, **self.camera)
        self._send()

    def frame(self, source, frame) -> None:
        size = (frame.width, frame.height)
        now = clock.now()
        switched = self._spectrum(frame)
        if size != self.size:                       # the first frame: what the source really delivers
            from posed.hal import scale_factor, working_size

            self.size = size
            ww, wh = working_size(*size, self.rt.ring.spec.capacity_px)
            self.camera.update(frame_width=size[0], frame_height=size[1], working_width=ww, working_height=wh,
                               scale=scale_factor(*size, self.rt.ring.spec.capacity_px))
            self.rt.log.info("frame_size", source_width=size[0], source_height=size[1], working_width=ww,
                             working_height=wh, scaled=ww != size[0],
                             slot_pixels=self.rt.ring.spec.capacity_px)
            self._send()
        elif now >= self.next_refresh:              # counters (frames, clock jumps, corrupt ...) once a second
            self.next_refresh = now + 1.0
            self.camera.update(_info(source))
            jumps = int(self.camera.get("clock_jumps", 0) or 0)
            if jumps > self.jumps:
                self.jumps = jumps
                self.problem(f"{self.camera.get('name', 'the source')}: its timestamps jumped ({jumps} clock "
                             "jumps so far: a repeated or backward timestamp, or a leap of more than a minute); "
                             "each such frame was placed one frame period after the one before",
                             "none needed; if the recording's timestamps are wrong, re-record it", warn=True)
            else:
                self._send()
        elif switched:
            self._send()

    def _spectrum(self, frame) -> bool:
        """Note the image the frame carries (colour, or infrared in a dark room); True when that changed. Each
        switch is logged once (the first frame's colour is no news)."""
        spectrum = getattr(frame, "spectrum", "colour")
        was = self.spectrum.get("spectrum")
        if spectrum == was:
            return False
        self.spectrum = {"spectrum": spectrum, "spectrum_since_unix": round(clock.wall_from_monotonic(frame.t), 3)}
        self.camera.update(self.spectrum)
        if spectrum == "infrared":
            self.rt.log.info("camera_dark", note="camera: dark, watching by infrared", spectrum=spectrum)
        elif was is not None:
            self.rt.log.info("camera_light", note="camera: light again, colour", spectrum=spectrum)
        return True

    def problem(self, error: str, fix: str, warn: bool = False) -> None:
        now = clock.now()
        if warn:
            self.rt.log.warning("clock_jump", error=error, fix=fix)
        self.last_problem = {"error": error, "fix": fix}
        if now >= self.next_problem or warn:
            self.next_problem = now + 0.5
            self._send()

    def privacy(self, paused: bool, pause) -> None:
        """A pause for privacy began or ended: the camera info says so (the supervisor's status)."""
        if paused:
            self.camera["paused_until_unix"] = round(pause.until_unix, 3)
        else:
            self.camera.pop("paused_until_unix", None)
        self._send()

    def ended(self, source) -> None:
        self.camera.update(_info(source) if source is not None else {})
        self.camera["state"] = "ended"
        self.rt.log.info("recording_ended", frames=int(self.rt.row.get("frames")),
                         bad_frames=int(self.rt.row.get("bad_frames")))
        self._send()

    def lost(self, error: str) -> None:
        self.camera.update(state="lost", error=error)
        self.rt.log.warning("camera_lost", error=error)
        self._send()

    def back(self, source) -> None:
        """Frames again after an unplug (the source reconnected by itself)."""
        self.camera.pop("error", None)
        self.camera.update(_info(source))
        self.rt.log.info("camera_back", **{k: v for k, v in self.camera.items() if k in ("name", "kind", "state")})
        self._send()


def _kind(info: dict) -> str:
    kind = str(info.get("kind", ""))
    return kind if kind in ("file", "v4l2", "realsense") else (kind or "source")


def _timeout_fix(src_cfg) -> str:
    if src_cfg.type == "file":
        return ("none needed if the recording has a gap there (a paced replay waits for each frame's time); "
                "else check the file, or replay it unpaced (source.realtime=false)")
    return "check the camera: its cable, power and that no other program holds it (source.read_timeout_s)"


def _bad_frame(rt: StageRuntime, throttle: Throttle, news: _News, error: str, pixels: int | None,
               source=None, fix: str = "") -> None:
    """Skip and count a frame that cannot be used; log it (at most a few lines a minute) with the fix that
    fits what was wrong (the source's own when it gave one: a covered lens, a camera's cable), and tell the
    supervisor."""
    rt.bad_frame()
    fix = fix or _corrupt_fix(pixels, source)
    news.problem(error, fix)
    suppressed = throttle.allow("bad_frame")
    if suppressed is not None:
        rt.log.warning("frame_skipped", error=error, fix=fix, bad_frames=int(rt.row.get("bad_frames")),
                       suppressed=suppressed)


def _corrupt_fix(pixels: int | None, source) -> str:
    from pathlib import Path

    if pixels:
        return too_large_fix(pixels)
    kind = getattr(source, "kind", "")
    path = getattr(getattr(source, "inner", source), "path", "") or ""
    if kind == "file" and path and (Path(path).is_dir() or Path(path).suffix.lower() in
                                    (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp", ".ppm", ".pgm")):
        return "replace or delete the image named in the error"
    if kind == "file":
        return ("the video does not decode there: re-encode it (ffmpeg -i IN.mp4 -c:v libx264 OUT.mp4) or "
                "record it again")
    return "check the camera's cable and pixel format (source.mjpg); the frames it sends do not decode"


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
    from posed.hal import ReplayClock
    from posed.landmarks import RecordingError, RecordingProblem, RecordingSides, iter_recording

    src = rt.config.source
    thinner = _Thinner(rt.config.pipeline.target_fps)
    problems = put_back = 0
    first = True
    line = ReplayClock()             # the capture clock of every replay (hal.clock): no repeats, no leaps
    t_offset = 0.0                   # recording seconds of the passes before this one
    seq_offset = 0                   # seq continues over the passes of a loop
    last_rel = 0.0
    last_seq = -1
    passes = 0
    info: dict = {}
    problem: dict | None = None
    gate = _gate(rt)
    was_paused = False
    while True:
        try:
            header, stream = iter_recording(src.path)
        except RecordingError as exc:
            rt.fatal(str(exc), fix="check source.path (or --source file:PATH.landmarks.jsonl)")
        period = 1.0 / header.fps if header.fps and header.fps > 0 else 1.0 / src.fps
        if first:
            rt.row.set_camera("open")
            info = {"kind": "file", "what": "landmark recording", "name": f"file:{src.path}",
                    "fps": header.fps, "image_size": list(header.image_size)}
            rt.report(camera=info)
            rt.log.info("recording_open", **info)
            rt.ready()
            rt.wait_go()
            first = False
            t_start = clock.now()
        intrinsics = header.camera
        # left and right put back where the recording's extractor flipped them, as posed fit does
        sides = RecordingSides() if RecordingSides.needed(header, rt.config.landmarks.keep_sides) else None
        t_first: float | None = None
        seq_first: int | None = None
        pass_frames = 0
        for item in stream:
            rt.beat()
            rt.check_stop()
            if isinstance(item, RecordingProblem):
                problems += 1
                rt.bad_frame()                     # a frame line that cannot be used: skipped and counted
                if problems <= 3:
                    rt.log.warning("recording_problem", problem=str(item))
                problem = {"error": str(item), "fix": "repair or re-record the recording (the line named)"}
                rt.report(camera=info, problem=problem)
                continue
            if t_first is None:
                t_first = item.t
            last_rel = item.t - t_first
            jumps = line.jumps
            t_capture = line.map(t_start + t_offset + last_rel, period)   # the recording's time line
            if line.jumps > jumps and line.jumps <= 3:
                rt.log.warning("clock_jump", seq=item.seq, step_s=round(line.last_jump_s, 3),
                               note="a repeated, backward or leaping timestamp: placed one frame period after "
                                    "the frame before")
            if src.realtime:
                sleep_until(t_capture, rt, slice_s=0.05)
            paused = gate.paused()
            if paused != was_paused:            # paused for privacy: the recording runs on, unseen
                was_paused = paused
                rt.row.set_camera("paused" if paused else "open")
            if seq_first is None:
                seq_first = item.seq
            seq = item.seq if passes == 0 else seq_offset + item.seq - seq_first
            last_seq = seq
            pass_frames += 1
            if paused:
                continue
            if not thinner.take(t_capture):
                rt.skip()
                continue
            if not src.realtime:
                rt.wait_taken()
            with rt.step():
                t_in = clock.now()
                frame = replace(item, t=t_capture, seq=seq)   # depth_m, gravity and unknown fields travel on
                if sides is not None:
                    frame = sides(frame)
                msg = LandmarkMsg(frame, t_capture, tuple(header.image_size), intrinsics, (),
                                  None if src.realtime else t_in)
                rt.send(msg)
            rt.done(clock.now() - t_in, origin(msg))
        put_back += 0 if sides is None else sides.frames_put_back
        if not src.loop or pass_frames == 0:
            break
        t_offset += last_rel + period            # the next pass continues the time line ...
        seq_offset = last_seq + 1                # ... and seq, as hal's replays do
        passes += 1
    rt.row.set_camera("ended")
    rt.report(camera={**info, "state": "ended", "clock_jumps": line.jumps}, **({"problem": problem} if problem else {}))
    rt.log.info("recording_ended", frames=int(rt.row.get("frames")), problems=problems, clock_jumps=line.jumps,
                sides_put_back=put_back)
    while True:
        sleep_until(clock.now() + 0.2, rt)
