"""Lossless playback of a RealSense recording: every frame once, each colour frame with its own depth.

``rs.pipeline`` cannot do this: its output queue holds one frameset and drops the older one when the reader
is slow, and its framesets pair each new frame with the last frame of the other stream, so a colour frame may
come with the depth of the frame before (which one depends on thread scheduling). This player opens the
recorded sensors directly (``context.load_device``, non-real-time playback) and passes their frames through
a small queue: the frame callback waits while ``QUEUE_FRAMES`` frames are queued, and in non-real-time mode
a waiting callback holds the file reader back, so a slow consumer slows playback down instead of losing frames. Colour frames are paired with
the depth frame nearest in time (within half a frame period), and when asked (``start(..., infrared=True)``)
with the left infrared imager's frame (stream index 1) nearest in time too; colour and its partners become one
frameset, for ``rs.align`` and the infrared image (``get_infrared_frame(1)``). A colour frame is handed out
once each partner stream has a frame at or after its time (or the file has ended).

The playback device starts reading when its first sensor starts, and drops frames of a sensor not started
yet; so once all are started the file is rewound (``seek(0)``) and the frames already seen come again: a frame
not later than the last one of its stream is a repeat and is dropped.

A recording's accelerometer stream (a D435i's, or what ``posed record`` wrote), and its gyro stream when it has
one, are played too when ``start`` is given a ``motion`` callback: their frames go to that callback
(:func:`hal.imu.sample_sink`) as they are read, never into the queue, and never hold the reader back.

It offers the part of the ``rs.pipeline`` interface :mod:`hal.realsense` uses (``start``,
``try_wait_for_frames``, ``stop``) plus ``finished()``: the file has been read and every frame handed out.
"""

from __future__ import annotations

import datetime
import queue
import threading
import time
from collections import deque
from collections.abc import Callable
from typing import Any

# The left infrared imager, in whose frame a D4xx computes depth (the right one is index 2).
INFRARED_INDEX = 1
# Frames in flight between librealsense's playback threads and the reader (the back-pressure window).
QUEUE_FRAMES = 4
# A callback blocked on the full queue re-checks this often whether the player is stopping.
PUT_SLICE_S = 0.02
# A playback that never started a stream within this long after start() counts as ended (an empty file).
START_GRACE_S = 2.0


class PlaybackProfile:
    """What ``pipeline.start`` returns, as far as :mod:`hal.realsense` uses it."""

    def __init__(self, device: Any, streams: list[Any]) -> None:
        self._device = device
        self._streams = streams

    def get_device(self) -> Any:
        return self._device

    def get_streams(self) -> list[Any]:
        return list(self._streams)


class PlaybackPipeline:
    """Plays one recording once (``start(path, depth)``); framesets of colour + its own depth, none lost."""

    def __init__(self, rs: Any) -> None:
        self._rs = rs
        self._queue: queue.Queue = queue.Queue()  # bounded by _on_frame, except while rewinding at start
        self._stopping = threading.Event()
        self._rewinding = True
        self._last: dict[Any, tuple[float, int]] = {}  # per stream: (timestamp, number) of the last frame
        self._sensors: list[Any] = []
        self._colours: deque = deque()
        self._partners: dict[Any, deque] = {}     # depth / infrared stream -> its frames not handed out yet
        self._tolerance_ms = 0.0
        self._seen = False
        self._started_at = 0.0
        self._playback: Any = None
        self._pair_with: list[Any] = []
        self._composer: Any = None
        self._composed: Any = None
        self._motion: Callable[[Any], None] | None = None

    # -- life cycle ---------------------------------------------------------------------------------------
    def start(self, path: str, depth: bool, motion: Callable[[Any], None] | None = None,
              infrared: bool = False) -> PlaybackProfile:
        """Play ``path``: colour (and its depth when ``depth``, its left infrared image when ``infrared`` and
        the recording has one); accelerometer and gyro frames to ``motion``, if given."""
        rs = self._rs
        self._motion = motion
        self._ctx = rs.context()
        dev = self._ctx.load_device(path)  # RuntimeError for a file librealsense cannot read
        self._playback = dev.as_playback()
        self._playback.set_real_time(False)  # before streaming: the reader then waits for the callbacks
        wanted = (rs.stream.color, rs.stream.depth) if depth else (rs.stream.color,)
        if infrared:
            wanted += (rs.stream.infrared,)
        motion_streams = (rs.stream.accel, rs.stream.gyro)
        if motion is not None:
            wanted += motion_streams
        chosen: dict[Any, tuple[Any, Any]] = {}
        for sensor in dev.query_sensors():
            for p in sensor.get_stream_profiles():
                if p.stream_type() == rs.stream.infrared and p.stream_index() != INFRARED_INDEX:
                    continue    # the right imager: depth is not on its grid
                if p.stream_type() in wanted and p.stream_type() not in chosen:
                    chosen[p.stream_type()] = (sensor, p)
        self._partners = {kind: deque() for kind in (rs.stream.depth, rs.stream.infrared) if kind in chosen}
        periods = [1000.0 / p.fps() for kind, (_, p) in chosen.items() if p.fps() > 0 and kind not in motion_streams]
        self._tolerance_ms = 0.5 * max(periods) if periods else 0.0
        by_sensor: dict[int, tuple[Any, list[Any]]] = {}
        for sensor, p in chosen.values():
            by_sensor.setdefault(id(sensor), (sensor, []))[1].append(p)

        def combine(frame: Any, source: Any) -> None:
            source.frame_ready(source.allocate_composite_frame([frame, *self._pair_with]))

        self._composer = rs.processing_block(combine)
        self._composed = rs.frame_queue(1, keep_frames=True)
        self._composer.start(self._composed)
        self._started_at = time.monotonic()
        try:
            for sensor, profiles in by_sensor.values():
                sensor.open(profiles)
                self._sensors.append(sensor)
            for sensor in self._sensors:
                sensor.start(self._on_frame)
            self._playback.seek(datetime.timedelta(0))  # frames of a sensor started late were dropped: again
            self._rewinding = False
        except RuntimeError:
            self.stop()
            raise
        return PlaybackProfile(dev, [p for _, p in chosen.values()])

    def stop(self) -> None:
        self._stopping.set()  # a callback blocked on the full queue gives up, so the sensors can stop
        for sensor in self._sensors:
            for action in (sensor.stop, sensor.close):
                try:
                    action()
                except RuntimeError:
                    pass
        self._sensors = []
        self._colours.clear()
        for frames in self._partners.values():
            frames.clear()
        while True:
            try:
                self._queue.get_nowait()
            except queue.Empty:
                break

    def _on_frame(self, frame: Any) -> None:
        """librealsense's playback thread: hand the frame over, waiting while the queue is full."""
        self._seen = True
        stream = frame.get_profile().stream_type()
        ts, number = frame.get_timestamp(), frame.get_frame_number()
        last = self._last.get(stream)
        if last is not None and (ts < last[0] or (ts, number) == last):
            return  # seen before the rewind
        self._last[stream] = (ts, number)
        if stream in (self._rs.stream.accel, self._rs.stream.gyro):
            if self._motion is not None:
                self._motion(frame)
            return
        frame.keep()
        # while rewinding (start) the reader must not wait: seek() waits for it
        while not self._rewinding and self._queue.qsize() >= QUEUE_FRAMES and not self._stopping.is_set():
            time.sleep(PUT_SLICE_S / 4)
        self._queue.put(frame)

    # -- reading ------------------------------------------------------------------------------------------
    def try_wait_for_frames(self, timeout_ms: int = 5000) -> tuple[bool, Any]:
        """(True, frameset of one colour frame + its depth and infrared) or (False, None) when none is ready in
        time."""
        deadline = time.monotonic() + timeout_ms / 1000.0
        while True:
            colour, partners, ready = self._decide(final=False)
            if ready:
                return True, self._compose(colour, partners)
            ended = self._reader_done()  # checked before the queue: all frames were queued before it stopped
            try:
                frame = self._queue.get(timeout=min(PUT_SLICE_S, max(0.0, deadline - time.monotonic())))
            except queue.Empty:
                if ended:
                    colour, partners, ready = self._decide(final=True)
                    if ready:
                        return True, self._compose(colour, partners)
                if time.monotonic() >= deadline:
                    return False, None
                continue
            stream = frame.get_profile().stream_type()
            (self._colours if stream == self._rs.stream.color else self._partners[stream]).append(frame)

    def finished(self) -> bool:
        """The recording has been read to its end and every frame of it handed out."""
        return self._reader_done() and self._queue.empty() and not self._colours

    def _reader_done(self) -> bool:
        try:
            stopped = self._playback.current_status() == self._rs.playback_status.stopped
        except RuntimeError:
            return True
        return stopped and (self._seen or time.monotonic() - self._started_at > START_GRACE_S)

    def _decide(self, final: bool) -> tuple[Any, list[Any], bool]:
        """The first colour frame and its partners (depth, infrared: those within half a frame period), when
        that can be decided: each partner stream has a frame at or after its time, or (``final``) no more frames
        will come."""
        if not self._colours:
            return None, [], False
        ts = self._colours[0].get_timestamp()
        if not final and any(not any(f.get_timestamp() >= ts for f in frames) for frames in self._partners.values()):
            return None, [], False
        colour = self._colours.popleft()
        partners = [f for f in (self._nearest(frames, ts) for frames in self._partners.values()) if f is not None]
        return colour, partners, True

    def _nearest(self, frames: deque, ts: float) -> Any:
        """The frame of one partner stream nearest to ``ts`` (within the tolerance) or None; the frames before
        it are dropped, it is kept (a faster colour stream may pair with it again)."""
        after = next((i for i, f in enumerate(frames) if f.get_timestamp() >= ts), None)
        candidates = [i for i in (after, (len(frames) if after is None else after) - 1)
                      if i is not None and 0 <= i < len(frames)]
        best = min(candidates, key=lambda i: abs(frames[i].get_timestamp() - ts), default=None)
        if best is None or abs(frames[best].get_timestamp() - ts) > self._tolerance_ms:
            for _ in range(after if after is not None else len(frames)):
                frames.popleft()  # older than this colour frame: no later colour frame is nearer
            return None
        for _ in range(best):
            frames.popleft()
        return frames[0]

    def _compose(self, colour: Any, partners: list[Any]) -> Any:
        self._pair_with = partners
        try:
            self._composer.invoke(colour)
            return self._composed.wait_for_frame(1000).as_frameset()
        finally:
            self._pair_with = []
