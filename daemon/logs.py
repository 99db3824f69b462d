"""structlog set up once per process: readable on a terminal, JSON lines otherwise (journald reads stdout).

No per-frame log lines anywhere: stages log state changes and a periodic ``stats`` event.
"""

from __future__ import annotations

import logging
import os
import sys

import structlog

from daemon import journald

_LEVELS = {"debug": logging.DEBUG, "info": logging.INFO, "warning": logging.WARNING, "error": logging.ERROR}
_configured: tuple[str, str, str | None] | None = None


class _Live:
    """``sys.stdout`` or ``sys.stderr`` as it is when a line is written (not when logging was configured): a
    process whose stream is replaced later (a test's capture, a redirect) never writes to a closed one."""

    def __init__(self, name: str) -> None:
        self.name = name

    def write(self, text: str) -> int:
        try:
            return getattr(sys, self.name).write(text)
        except BrokenPipeError:
            _drop_stream(self.name)
            return len(text)

    def flush(self) -> None:
        try:
            getattr(sys, self.name).flush()
        except BrokenPipeError:
            _drop_stream(self.name)

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
