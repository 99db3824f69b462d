"""structlog set up once per process: readable on a terminal, JSON lines otherwise (journald reads stdout).

No per-frame log lines anywhere: stages log state changes and a periodic ``stats`` event.

A reader that stops reading (a paused ``less``, a terminal stopped with Ctrl-S) must not stop the daemon: a
log line is written at once when the stream can take it without waiting (``select``, a line of at most
PIPE_BUF bytes: pipes write those whole); otherwise it waits in a bounded spill queue (``SPILL_BYTES``) that a
thread writes out in order, blocking on its own. Lines that do not fit are dropped and counted, and once
the reader is back a ``log_lines_dropped`` line says how many. At exit the queue gets ``DRAIN_S`` to empty.
"""

from __future__ import annotations

import atexit
import collections
import logging
import os
import select
import sys
import threading

import structlog

from posed.daemon import journald

_LEVELS = {"debug": logging.DEBUG, "info": logging.INFO, "warning": logging.WARNING, "error": logging.ERROR}
_configured: tuple[str, str, str | None] | None = None
SPILL_BYTES = 1 << 20     # log text waiting for a slow reader, per stream; beyond it lines are dropped
DRAIN_S = 1.0             # at exit, how long the waiting lines get
PIPE_BUF = 4096           # Linux: a pipe write of at most this many bytes is atomic


class _Live:
    """``sys.stdout`` or ``sys.stderr`` as it is when a line is written (not when logging was configured): a
    process whose stream is replaced later (a test's capture, a redirect) never writes to a closed one."""

    def __init__(self, name: str) -> None:
        self.name = name
        self._line: list[str] = []                       # what print() wrote since its last flush
        self._cond = threading.Condition()
        self._spill: collections.deque[str] = collections.deque()
        self._spill_bytes = 0
        self._writer: threading.Thread | None = None
        self._busy = False                                # the writer thread is writing a line
        self.dropped = 0                                  # lines that did not fit the spill queue
        self._dropped_told = 0

    def write(self, text: str) -> int:
        with self._cond:
            self._line.append(text)
        return len(text)

    def flush(self) -> None:
        with self._cond:
            text, self._line = "".join(self._line), []
            if text:
                self._emit(text)

    def _emit(self, text: str) -> None:
        with self._cond:
            if not self._spill and self._ready(text):
                self._write_now(text)
                return
            if self._spill_bytes + len(text) > SPILL_BYTES:
                self.dropped += 1
                return
            self._spill.append(text)
            self._spill_bytes += len(text)
            if self._writer is None:
                self._writer = threading.Thread(target=self._drain, name=f"log-{self.name}", daemon=True)
                self._writer.start()
                atexit.register(self.wait_drained, DRAIN_S)
            self._cond.notify()

    def _ready(self, text: str) -> bool:
        """The stream takes ``text`` now without waiting (or cannot be asked: no file descriptor)."""
        stream = getattr(sys, self.name)
        try:
            fd = stream.fileno()
        except (AttributeError, OSError, ValueError):
            return True                                   # a StringIO, a test's capture: never waits
        if len(text.encode("utf-8", "replace")) > PIPE_BUF:
            return False
        try:
            return bool(select.select([], [fd], [], 0)[1])
        except (OSError, ValueError):
            return True

    def _write_now(self, text: str) -> None:
        try:
            stream = getattr(sys, self.name)
            stream.write(text)
            stream.flush()
        except BrokenPipeError:
            _drop_stream(self.name)

    def _drain(self) -> None:
        while True:
            with self._cond:
                self._busy = False
                while not self._spill:
                    self._cond.notify_all()               # wait_drained: all written
                    self._cond.wait()
                text = self._spill.popleft()
                self._spill_bytes -= len(text)
                told = self.dropped - self._dropped_told
                self._dropped_told = self.dropped
                self._busy = True
            self._write_fd(text)                         # may block on a paused reader: only this thread waits
            if told:
                self._write_fd(f'{{"event": "log_lines_dropped", "count": {told}, "stream": "{self.name}", '
                               f'"why": "the log reader did not keep up"}}\n')

    def _write_fd(self, text: str) -> None:
        """Write on the file descriptor itself: a thread blocked here holds none of the stream's locks, so
        the interpreter can still flush and exit while the reader is paused."""
        stream = getattr(sys, self.name)
        try:
            fd = stream.fileno()
            data = text.encode(getattr(stream, "encoding", None) or "utf-8", "replace")
            while data:
                data = data[os.write(fd, data):]
        except BrokenPipeError:
            _drop_stream(self.name)
        except (OSError, ValueError, AttributeError):
            pass

    def wait_drained(self, timeout_s: float) -> bool:
        """Wait up to ``timeout_s`` for the waiting lines to be written; True when none is left."""
        with self._cond:
            return self._cond.wait_for(lambda: not self._spill and not self._busy, timeout_s)

    def isatty(self) -> bool:
        return getattr(sys, self.name).isatty()


STDOUT, STDERR = _Live("stdout"), _Live("stderr")


def _drop_stream(name: str) -> None:
    """The reader of our stdout/stderr went away (``posed run | tee``, tee killed): point the file descriptor
    at /dev/null so that logging, and every later write, goes on silently instead of raising in the
    supervisor's loop or its signal handling (a broken log pipe must never stop the daemon)."""
    stream = getattr(sys, name)
    try:
        fd = stream.fileno()
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, fd)
        os.close(devnull)
    except (OSError, ValueError):
        return
    try:
        stream.flush()                 # what was buffered now goes to /dev/null
    except OSError:
        pass


def configure(level: str = "info", fmt: str = "auto", stream=None, robot: str | None = None) -> None:
    """Configure structlog for this process (default: to the current ``sys.stdout``); later calls with the
    same arguments do nothing. ``auto``: journald's own fields when journald is reachable
    (:mod:`daemon.journald`; ``robot`` is then each entry's POSED_ROBOT), else console on a TTY, else JSON."""
    global _configured
    if stream is None or stream is sys.stdout:
        stream = STDOUT
    elif stream is sys.stderr:
        stream = STDERR
    if fmt == "auto" and stream in (STDOUT, STDERR) and journald.reachable():
        fmt = "journal"
    if fmt == "auto":
        fmt = "console" if getattr(stream, "isatty", lambda: False)() else "json"
    if _configured == (level, fmt, robot) and stream is STDOUT:
        return
    if fmt == "journal":
        renderer = journald.Sender(robot, fallback=stream)
    else:
        renderer = (
            structlog.dev.ConsoleRenderer(colors=False)
            if fmt == "console"
            else structlog.processors.JSONRenderer(sort_keys=False)
        )
    structlog.configure(
        processors=[
            structlog.contextvars.merge_contextvars,
            structlog.processors.add_log_level,
            structlog.processors.TimeStamper(fmt="iso", utc=True),
            structlog.processors.StackInfoRenderer(),
            structlog.processors.format_exc_info,
            renderer,
        ],
        wrapper_class=structlog.make_filtering_bound_logger(_LEVELS[level]),
        logger_factory=structlog.PrintLoggerFactory(file=stream),
        cache_logger_on_first_use=False,
    )
    _configured = (level, fmt, robot) if stream is STDOUT else None


def get(name: str, **context):
    """A logger bound to a component name (e.g. ``get("capture", source="file")``)."""
    return structlog.get_logger().bind(component=name, **context)
