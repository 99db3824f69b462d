"""A UVC webcam through OpenCV's V4L2 backend, surviving unplugs.

Opening: ``cv2.VideoCapture(device, cv2.CAP_V4L2)`` with a device path (``/dev/video0``; better the stable
``/dev/v4l/by-id/...``) or an index (``0``). Settings are applied in the order V4L2 needs: FOURCC MJPG first
(``source.mjpg``), then width and height, then fps, then ``CAP_PROP_BUFFERSIZE`` (``source.buffer_size``,
default 1: the driver keeps no backlog); what the camera accepted is read back into ``info``.

A reader thread owns the capture and keeps only the newest frame; ``read(timeout)`` waits for a frame newer
than the last one returned, so it never blocks longer than its timeout even when the driver does. OpenCV's
own wait for a frame (``OPENCV_VIDEOIO_V4L_SELECT_TIMEOUT``, default 10 s, read once per process) is set to
``ceil(read_timeout_s)`` before the first camera is opened, unless the environment already sets it.

Faults: a read that times out raises SourceTimeout; after ``timeouts_before_reopen`` in a row the camera is
closed and opened again. A failed grab (unplug: DQBUF fails, the handle is dead) releases the camera; reads
raise SourceDisconnected (the first one at once) while the thread reopens it with exponential backoff
(``reconnect_initial_s`` doubling up to ``reconnect_max_s``); frames flow again by themselves.

Timestamps: ``CAP_PROP_POS_MSEC`` of a V4L2 capture is the kernel's buffer time (uvcvideo: CLOCK_MONOTONIC, the
clock of ``time.monotonic()``), used when it is plausible (at most 1 s old); otherwise the arrival time.
Intrinsics: ``source.fx/fy/cx/cy`` in pixels of the delivered image (none when fx is 0).
"""

from __future__ import annotations

import math
import os
import threading
import time
from collections.abc import Callable
from typing import Any

import cv2
import numpy as np

from posed.hal.config import SourceConfig
from posed.hal.errors import SourceDisconnected, SourceError, SourceNotFound
from posed.hal.frame import Frame
from posed.hal.replay import as_bgr, config_intrinsics, fourcc_text
from posed.hal.source import Source

CaptureFactory = Callable[[Any, int], Any]


def opencv_capture(device: Any, api: int) -> Any:
    """The real hardware edge: an OpenCV capture."""
    return cv2.VideoCapture(device, api)


def device_target(device: str) -> int | str:
    """An index for ``"0"``, else the path as given."""
    text = device.strip()
    return int(text) if text.isdigit() else text


class V4L2Source(Source):
    """A V4L2 camera. ``capture_factory(device, cv2.CAP_V4L2)`` returns a capture object (default OpenCV's);
    tests pass a scripted one. ``info`` adds the size/fps/fourcc the camera accepted and the counters
    timeouts, reopens, disconnects, reconnect_attempts, dropped (frames replaced before anyone read them)."""

    kind = "v4l2"

    def __init__(self, config: SourceConfig, capture_factory: CaptureFactory | None = None,
                 clock=time.monotonic) -> None:
        super().__init__(config, f"v4l2:{config.device}")
        self._factory = capture_factory or opencv_capture
        self._real = capture_factory is None
        self._clock = clock
        self._cond = threading.Condition()
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self.accepted: dict[str, Any] = {}
        self.counters.update(timeouts=0, reopens=0, disconnects=0, reconnect_attempts=0, dropped=0)

    # -- opening ------------------------------------------------------------------------------------------
    def _connect(self) -> Any:
        """Open and configure the camera; raises SourceNotFound naming the device and what to check."""
        c = self.config
        target = device_target(c.device)
        cap = self._factory(target, cv2.CAP_V4L2)
        if cap is None or not cap.isOpened():
            if cap is not None:
                cap.release()
            if isinstance(target, str) and not os.path.exists(target):
                raise SourceNotFound(f"{c.device}: no such video device; plug the camera in, list cameras with "
                                     "`v4l2-ctl --list-devices`, prefer a stable /dev/v4l/by-id/... path", self.name)
            raise SourceNotFound(f"{c.device}: the video device cannot be opened (busy in another program, no "
                                 "permission — add the user to group 'video' — or not a capture device)", self.name)
        if c.mjpg:
            cap.set(cv2.CAP_PROP_FOURCC, cv2.VideoWriter_fourcc(*"MJPG"))
        cap.set(cv2.CAP_PROP_FRAME_WIDTH, c.width)
        cap.set(cv2.CAP_PROP_FRAME_HEIGHT, c.height)
        cap.set(cv2.CAP_PROP_FPS, c.fps)
        cap.set(cv2.CAP_PROP_BUFFERSIZE, c.buffer_size)
        self.accepted = {
            "width": int(cap.get(cv2.CAP_PROP_FRAME_WIDTH) or 0), "height": int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT)
                                                                            or 0),
            "fps": float(cap.get(cv2.CAP_PROP_FPS) or 0.0), "fourcc": fourcc_text(cap.get(cv2.CAP_PROP_FOURCC)),
            "buffer_size": int(cap.get(cv2.CAP_PROP_BUFFERSIZE) or 0)}
        return cap

    def _open(self) -> None:
        if self._real:
            os.environ.setdefault("OPENCV_VIDEOIO_V4L_SELECT_TIMEOUT",
                                  str(max(1, math.ceil(self.config.read_timeout_s))))
        cap = self._connect()
        self._stop.clear()
        self._latest: tuple[np.ndarray, float, int] | None = None
        self._returned_seq = -1
        self._seq = -1
        self._disconnect_events = 0
        self._seen_disconnects = 0
        self._consecutive_timeouts = 0
        self._reopen_requested = False
        self._next_attempt = 0.0
        self._backoff = self.config.reconnect_initial_s
        self._timestamp_source = ""
        self.state = "streaming"
        self._thread = threading.Thread(target=self._run, args=(cap,), name=f"hal-v4l2-{self.config.device}",
                                        daemon=True)
        self._thread.start()

    def _close(self) -> None:
        self._stop.set()
        with self._cond:
            self._cond.notify_all()
        thread, self._thread = self._thread, None
        if thread is not None:
            # A capture blocked in the driver returns within OpenCV's select timeout; the thread is a daemon,
            # so an even longer hang cannot keep the process alive.
            thread.join(timeout=self.config.read_timeout_s + 1.0)

    def _describe(self) -> dict[str, Any]:
        return {"device": self.config.device, "width": self.accepted.get("width", 0),
                "height": self.accepted.get("height", 0), "fps": self.accepted.get("fps", 0.0),
                "fourcc": self.accepted.get("fourcc", ""), "buffer_size": self.accepted.get("buffer_size", 0),
                "has_depth": False, "timestamps": getattr(self, "_timestamp_source", "")}

    # -- the reader thread --------------------------------------------------------------------------------
    def _run(self, cap: Any) -> None:
        try:
            while not self._stop.is_set():
                if cap is None:
                    cap = self._try_reconnect()
                    continue
                ok, image = cap.read()
                if self._stop.is_set():
                    break
                if self._reopen_requested:
                    self._reopen_requested = False
                    cap.release()
                    cap = None
                    self.count("reopens")
                    with self._cond:
                        self.state = "reconnecting"
                        self._next_attempt = self._clock()
                    continue
                if not ok or image is None:
                    cap.release()
                    cap = None
                    with self._cond:
                        self.count("disconnects")
                        self._disconnect_events += 1
                        self.state = "disconnected"
                        self._backoff = self.config.reconnect_initial_s
                        self._next_attempt = self._clock() + self._backoff
                        self._cond.notify_all()
                    continue
                self._publish(cap, image)
        finally:
            if cap is not None:
                cap.release()

    def _publish(self, cap: Any, image: np.ndarray) -> None:
        arrival = self._clock()
        t = arrival
        try:
            ms = float(cap.get(cv2.CAP_PROP_POS_MSEC))
        except (TypeError, ValueError, cv2.error):
            ms = 0.0
        if ms > 0 and 0.0 <= arrival - ms / 1000.0 <= 1.0:
            t = ms / 1000.0
            self._timestamp_source = "kernel"
        else:
            self._timestamp_source = "arrival"
        image = np.ascontiguousarray(as_bgr(np.asarray(image)))
        with self._cond:
            self._seq += 1
            if self._latest is not None and self._latest[2] > self._returned_seq:
                self.count("dropped")
            self._latest = (image, t, self._seq)
            self.state = "streaming"
            self._cond.notify_all()

    def _try_reconnect(self) -> Any:
        now = self._clock()
        if now < self._next_attempt:
            self._stop.wait(self._next_attempt - now)
            return None
        self.count("reconnect_attempts")
        try:
            cap = self._connect()
        except SourceError:
            with self._cond:
                self._backoff = min(self._backoff * 2.0, self.config.reconnect_max_s)
                self._next_attempt = self._clock() + self._backoff
            return None
        with self._cond:
            self.state = "streaming"
            self._backoff = self.config.reconnect_initial_s
            self._cond.notify_all()
        return cap

    # -- reading ------------------------------------------------------------------------------------------
    def _read(self, timeout_s: float) -> Frame:
        deadline = self._clock() + timeout_s
        with self._cond:
            while True:
                latest = self._latest
                if latest is not None and latest[2] > self._returned_seq:
                    image, t, seq = latest
                    self._returned_seq = seq
                    self._consecutive_timeouts = 0
                    return Frame(image=image, depth=None, depth_scale=0.0, t=t, seq=seq,
                                 intrinsics=config_intrinsics(self.config, image.shape[1], image.shape[0]))
                if self._disconnect_events > self._seen_disconnects:
                    self._seen_disconnects = self._disconnect_events
                    raise self._disconnected()
                remaining = deadline - self._clock()
                if remaining <= 0:
                    break
                self._cond.wait(remaining)
            if self.state in ("disconnected", "reconnecting"):
                raise self._disconnected()
            raise self._timed_out(timeout_s, self._request_reopen)

    def _request_reopen(self) -> None:
        """Too many timeouts in a row: the reader thread closes and opens the camera after its current read."""
        self._consecutive_timeouts = 0
        self._reopen_requested = True

    def _disconnected(self) -> SourceDisconnected:
        wait = max(0.0, self._next_attempt - self._clock())
        return SourceDisconnected(
            f"{self.name}: the camera is unplugged or stopped sending; reconnecting (next try in {wait:.1f} s, "
            f"{self.counters.get('reconnect_attempts', 0)} tries so far) — check the USB cable; frames resume by "
            "themselves", self.name)
