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

Bad frames (what a camera really sends when it misbehaves): a frame the driver hands over unconverted is made
usable when it can be (packed YUYV/UYVY as 2 channels or as the raw buffer; a raw MJPEG buffer, decoded), else
it is a corrupt frame: an empty frame, a buffer that is not an image, an MJPEG frame cut short. A frame whose
pixels are all the same colour (all black: a covered lens, a closed privacy shutter, a pitch-dark room; the
uniform green of a YUYV stream of zeros: a sensor or USB fault) cannot show anyone: it is not handed out either. Each read of such a frame raises SourceCorrupt
(counted as ``corrupt`` / ``blank``) naming what the camera sent and the fix (``exc.fix``), so the daemon
skips it, counts it and says it is blind, and why. A camera that sends the very same bytes over and over
(a stuck UVC stream: real sensors have noise, so two real frames are never equal) for ``FROZEN_AFTER_S`` is
treated as unplugged: it is closed and opened again with the reconnect backoff (counter ``frozen``), and reads
raise SourceDisconnected saying it froze. Whatever the capture object raises (``cv2.error`` from a driver)
is a failed grab, never the end of the reader thread: a dead thread would leave the camera silent for good.

Timestamps: ``CAP_PROP_POS_MSEC`` of a V4L2 capture is the kernel's buffer time (uvcvideo: CLOCK_MONOTONIC, the
clock of ``time.monotonic()``), used when it is plausible (at most 1 s old); otherwise the arrival time. A
frame's ``t`` never goes back from the one before (a switch between the two could step back).
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

from posed.hal.blank import BLANK_FIX, blank_message, is_blank
from posed.hal.config import SourceConfig
from posed.hal.errors import SourceCorrupt, SourceDisconnected, SourceNotFound
from posed.hal.frame import Frame
from posed.hal.replay import as_bgr, config_intrinsics, fourcc_text
from posed.hal.source import Source

CaptureFactory = Callable[[Any, int], Any]

# A camera that sends byte-identical frames for this long (and at least FROZEN_MIN_REPEATS times) is stuck.
FROZEN_AFTER_S = 2.0
FROZEN_MIN_REPEATS = 3
BAD_FRAME_FIX = ("check the camera's USB cable and port (a USB 2 port or hub short of bandwidth cuts MJPEG "
                 "frames short) and its pixel format (source.mjpg)")


def usable_image(image: Any, fourcc: str = "", size: tuple[int, int] = (0, 0)) -> tuple[np.ndarray | None, str]:
    """``(BGR image, "")`` from what a V4L2 capture returned, or ``(None, what is wrong with it)``.

    Accepted: BGR, grey, BGRA, 16-bit or float images (:func:`hal.replay.as_bgr`); packed YUV 4:2:2 as two
    channels (``fourcc`` UYVY, else YUYV), or as the raw buffer of the camera's ``size`` (width, height: 2
    bytes a pixel); a raw MJPEG buffer (a 1-D or one-row array starting with a JPEG marker), decoded."""
    if image is None:
        return None, "an empty frame (no pixels)"
    image = np.asarray(image)
    if image.size == 0:
        return None, f"an empty frame (shape {image.shape})"
    if image.ndim == 1 or (image.ndim == 2 and 1 in image.shape and image.dtype == np.uint8
                           and max(image.shape) > 64):
        raw = np.ascontiguousarray(image.reshape(-1))
        w, h = size
        if raw.dtype == np.uint8 and w > 0 and h > 0 and w % 2 == 0 and raw.size == w * h * 2 \
                and not (raw[0] == 0xFF and raw[1] == 0xD8):
            image = raw.reshape(h, w, 2)                         # packed YUV 4:2:2, unconverted
        elif raw.dtype != np.uint8 or raw.size < 4 or raw[0] != 0xFF or raw[1] != 0xD8:
            return None, (f"a raw buffer of {raw.size} values, not an image (the driver's pixel format was not "
                          "converted)")
        else:
            try:
                decoded = cv2.imdecode(raw, cv2.IMREAD_COLOR)
            except cv2.error:
                decoded = None
            if decoded is None or decoded.size == 0:
                return None, f"an MJPEG frame of {raw.size} bytes that does not decode (cut short or corrupt)"
            return decoded, ""
    if image.ndim == 3 and image.shape[2] == 2 and image.dtype == np.uint8:
        if image.shape[1] % 2:
            return None, f"a packed YUV 4:2:2 frame of odd width {image.shape[1]}"
        code = cv2.COLOR_YUV2BGR_UYVY if fourcc.upper() == "UYVY" else cv2.COLOR_YUV2BGR_YUYV
        return cv2.cvtColor(np.ascontiguousarray(image), code), ""
    if image.ndim not in (2, 3) or (image.ndim == 3 and image.shape[2] not in (1, 3, 4)):
        return None, f"a frame of shape {image.shape} {image.dtype}, not an image"
    try:
        return np.ascontiguousarray(as_bgr(image)), ""
    except (cv2.error, ValueError, TypeError) as exc:
        return None, f"a frame of shape {image.shape} {image.dtype} that cannot be converted ({exc})"


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
        self.counters.update(timeouts=0, reopens=0, disconnects=0, reconnect_attempts=0, dropped=0, corrupt=0,
                             blank=0, frozen=0)

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
        try:
            if c.mjpg:
                cap.set(cv2.CAP_PROP_FOURCC, cv2.VideoWriter_fourcc(*"MJPG"))
            cap.set(cv2.CAP_PROP_FRAME_WIDTH, c.width)
            cap.set(cv2.CAP_PROP_FRAME_HEIGHT, c.height)
            cap.set(cv2.CAP_PROP_FPS, c.fps)
            cap.set(cv2.CAP_PROP_BUFFERSIZE, c.buffer_size)
            self.accepted = {
                "width": int(cap.get(cv2.CAP_PROP_FRAME_WIDTH) or 0),
                "height": int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT) or 0),
                "fps": float(cap.get(cv2.CAP_PROP_FPS) or 0.0), "fourcc": fourcc_text(cap.get(cv2.CAP_PROP_FOURCC)),
                "buffer_size": int(cap.get(cv2.CAP_PROP_BUFFERSIZE) or 0)}
        except Exception as exc:  # cv2.error from a device that went away while it was being set up
            _release(cap)
            raise SourceNotFound(f"{c.device}: the camera opened but cannot be set up ({type(exc).__name__}: "
                                 f"{str(exc).strip()[:200]}); check its cable, or unplug and plug it in again",
                                 self.name) from exc
        return cap

    def _open(self) -> None:
        if self._real:
            os.environ.setdefault("OPENCV_VIDEOIO_V4L_SELECT_TIMEOUT",
                                  str(max(1, math.ceil(self.config.read_timeout_s))))
        cap = self._connect()
        self._stop.clear()
        # (image or None, t, seq, what is wrong with it): the newest frame, or the newest bad one
        self._latest: tuple[np.ndarray | None, float, int, str] | None = None
        self._returned_seq = -1
        self._seq = -1
        self._disconnect_events = 0
        self._seen_disconnects = 0
        self._consecutive_timeouts = 0
        self._reopen_requested = False
        self._next_attempt = 0.0
        self._backoff = self.config.reconnect_initial_s
        self._timestamp_source = ""
        self._last_t: float | None = None
        self._why_lost = ""
        self._forget_frames()
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
                try:
                    ok, image = cap.read()
                except Exception as exc:  # cv2.error from the driver, anything from a capture: a failed grab
                    ok, image = False, None
                    why = f"reading it failed ({type(exc).__name__}: {str(exc).strip()[:200]})"
                else:
                    why = ""
                if self._stop.is_set():
                    break
                if self._reopen_requested:
                    self._reopen_requested = False
                    _release(cap)
                    cap = None
                    self.count("reopens")
                    with self._cond:
                        self.state = "reconnecting"
                        self._next_attempt = self._clock()
                    continue
                if ok and image is not None:
                    try:
                        frozen = self._publish(cap, image)
                    except Exception as exc:  # never let a frame end the thread (the camera would go silent)
                        frozen = False
                        self._publish_bad(f"a frame that cannot be used ({type(exc).__name__}: {exc})",
                                          BAD_FRAME_FIX)
                    if not frozen:
                        continue
                    why = (f"the camera sent the same image over and over for {FROZEN_AFTER_S:.0f} s (frozen: a "
                           "stuck USB stream)")
                    self.count("frozen")
                _release(cap)
                cap = None
                with self._cond:
                    self.count("disconnects")
                    self._disconnect_events += 1
                    self._why_lost = why
                    self.state = "disconnected"
                    self._backoff = self.config.reconnect_initial_s
                    self._next_attempt = self._clock() + self._backoff
                    self._cond.notify_all()
        finally:
            if cap is not None:
                _release(cap)

    def _forget_frames(self) -> None:
        """Start the frozen-frame watch again (a new or reopened capture)."""
        self._previous: np.ndarray | None = None
        self._same_since: float | None = None
        self._same_count = 0

    def _publish(self, cap: Any, image: np.ndarray) -> bool:
        """Hand ``image`` out as the newest frame (or as a bad one); True when the camera is frozen."""
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
        if self._last_t is not None and t <= self._last_t:     # never back (a switch kernel <-> arrival)
            t = max(arrival, self._last_t + 1e-6) if arrival > self._last_t else self._last_t + 1e-6
        self._last_t = t
        raw = np.asarray(image)
        bgr, why = usable_image(raw, self.accepted.get("fourcc", ""),
                                (self.accepted.get("width", 0), self.accepted.get("height", 0)))
        if bgr is None:
            self._forget_frames()
            self._publish_bad(f"the camera sent {why}", BAD_FRAME_FIX, t)
            return False
        if is_blank(bgr):        # blank frames are all alike: said as blank (not cured by a reopen), not frozen
            self._forget_frames()
            self.count("blank")
            self._publish_bad(blank_message(bgr), BLANK_FIX, t, count=False)
            return False
        # every 16th byte: real sensor noise changes those between any two frames; a stuck stream changes none
        signature = np.ascontiguousarray(raw).reshape(-1)[::16].copy()
        if self._previous is not None and signature.shape == self._previous.shape \
                and np.array_equal(signature, self._previous):
            self._same_count += 1
            if self._same_since is None:
                self._same_since = arrival
            if self._same_count >= FROZEN_MIN_REPEATS and arrival - self._same_since >= FROZEN_AFTER_S:
                self._forget_frames()
                return True
        else:
            self._same_since = None
            self._same_count = 0
            self._previous = signature
        with self._cond:
            self._seq += 1
            if self._latest is not None and self._latest[2] > self._returned_seq:
                self.count("dropped")
            self._latest = (bgr, t, self._seq, "")
            self.state = "streaming"
            self._cond.notify_all()
        return False

    def _publish_bad(self, why: str, fix: str, t: float | None = None, count: bool = True) -> None:
        """A frame that cannot be used: the next read raises SourceCorrupt saying ``why`` (the seq is used up,
        so a bad frame shows as a gap, as a lost frame does)."""
        with self._cond:
            if count:
                self.count("corrupt")
            self._seq += 1
            self._latest = (None, self._clock() if t is None else t, self._seq, why)
            self._bad_fix = fix
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
        except Exception:  # SourceError, or whatever a half-present device makes OpenCV raise
            with self._cond:
                self._backoff = min(self._backoff * 2.0, self.config.reconnect_max_s)
                self._next_attempt = self._clock() + self._backoff
            return None
        with self._cond:
            self.state = "streaming"
            self._backoff = self.config.reconnect_initial_s
            self._forget_frames()
            self._cond.notify_all()
        return cap

    # -- reading ------------------------------------------------------------------------------------------
    def _read(self, timeout_s: float) -> Frame:
        deadline = self._clock() + timeout_s
        thread = self._thread
        if thread is not None and not thread.is_alive() and not self._stop.is_set():
            # the reader thread ended without being stopped (it must not; if it ever does, the camera would stay
            # silent for good): start another one, which reconnects the camera
            self._thread = threading.Thread(target=self._run, args=(None,), name=thread.name, daemon=True)
            self._thread.start()
        with self._cond:
            while True:
                latest = self._latest
                if latest is not None and latest[2] > self._returned_seq:
                    image, t, seq, why = latest
                    self._returned_seq = seq
                    self._consecutive_timeouts = 0
                    if image is None:
                        raise SourceCorrupt(f"{self.name}: {why}; skipping it — "
                                            f"{getattr(self, '_bad_fix', BAD_FRAME_FIX)}", self.name,
                                            fix=getattr(self, "_bad_fix", BAD_FRAME_FIX))
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
        why = getattr(self, "_why_lost", "") or "the camera is unplugged or stopped sending"
        return SourceDisconnected(
            f"{self.name}: {why}; reconnecting (next try in {wait:.1f} s, "
            f"{self.counters.get('reconnect_attempts', 0)} tries so far) — check the USB cable; frames resume by "
            "themselves", self.name)


def _release(cap: Any) -> None:
    """Release a capture; a capture that raises on release (an unplugged device) is gone anyway."""
    try:
        cap.release()
    except Exception:
        pass
