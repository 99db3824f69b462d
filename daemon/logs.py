"""structlog set up once per process: readable on a terminal, JSON lines otherwise (journald reads stdout).

No per-frame log lines anywhere: stages log state changes and a periodic ``stats`` event.
"""

from __future__ import annotations

import logging
import sys

import structlog

_LEVELS = {"debug": logging.DEBUG, "info": logging.INFO, "warning": logging.WARNING, "error": logging.ERROR}
_configured: tuple[str, str] | None = None


def configure(level: str = "info", fmt: str = "auto", stream=None) -> None:
    """Configure structlog for this process; later calls with the same arguments do nothing."""
    global _configured
    stream = stream or sys.stdout
    if fmt == "auto":
        fmt = "console" if getattr(stream, "isatty", lambda: False)() else "json"
    if _configured == (level, fmt) and stream is sys.stdout:
        return
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
    _configured = (level, fmt)


def get(name: str, **context):
    """A logger bound to a component name (e.g. ``get("capture", source="file")``)."""
    return structlog.get_logger().bind(component=name, **context)
