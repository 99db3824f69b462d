"""structlog events to journald as structured entries (``systemd.journal``), so that e.g.
``journalctl -u posed POSED_STAGE=fitting`` or ``journalctl -u posed PRIORITY=3`` select them.

Used when journald is reachable: the process's stdout or stderr is the journal stream systemd connected
(``$JOURNAL_STREAM`` names its device and inode, systemd.exec(5)), journald's socket exists and systemd-python
is installed. Elsewhere (a terminal, a pipe, a container without journald) :mod:`daemon.logs` writes console or
JSON lines as before.

Fields of each entry (:func:`fields`):

    MESSAGE            the event as one JSON line (what the JSON format prints)
    PRIORITY           syslog level from the structlog level: debug 7, info 6, warning 4, error 3, critical 2
    SYSLOG_IDENTIFIER  posed
    POSED_EVENT        the structlog event name (``stage_ready``, ``fall_event``, ``stats`` ...)
    POSED_STAGE        the component: capture, landmarks, fitting, publisher, supervisor, ...
    POSED_ROBOT        ``robot_id`` of the config
    POSED_EVENT_ID     a fall event's id (the ``event_id`` key, or ``id`` of a ``fall_event*`` event)
    POSED_<KEY>        every other key of the event, upper-cased (non-strings as JSON)
"""

from __future__ import annotations

import json
import os
import re
import sys
from collections.abc import Callable

import structlog

SOCKET = "/run/systemd/journal/socket"
PRIORITIES = {"debug": 7, "info": 6, "notice": 5, "warning": 4, "warn": 4, "error": 3, "exception": 3,
              "critical": 2, "fatal": 2}
_NOT_FIELD = re.compile(r"[^A-Z0-9_]")
MAX_VALUE = 4096       # a field longer than this is cut (MESSAGE keeps the whole event)


def reachable(environ: dict | None = None, socket_path: str = SOCKET, streams=None) -> bool:
    """True when this process logs to journald: ``$JOURNAL_STREAM`` is the device:inode of its stdout or
    stderr, journald's socket exists and ``systemd.journal`` imports."""
    env = os.environ if environ is None else environ
    stream = env.get("JOURNAL_STREAM", "")
    if not stream or not os.path.exists(socket_path):
        return False
    try:
        dev, ino = (int(x) for x in stream.split(":"))
    except ValueError:
        return False
    for s in (sys.stdout, sys.stderr) if streams is None else streams:
        try:
            st = os.fstat(s.fileno())
        except (OSError, ValueError, AttributeError):
            continue
        if (st.st_dev, st.st_ino) == (dev, ino):
            try:
                import systemd.journal  # noqa: F401
            except ImportError:
                return False
            return True
    return False


def _field_name(key: str) -> str:
    name = _NOT_FIELD.sub("_", str(key).upper()).strip("_")
    return ("POSED_" + name)[:64]


def _text(value) -> str:
    text = value if isinstance(value, str) else json.dumps(value, default=str)
    return text[:MAX_VALUE]


def fields(event_dict: dict, robot: str | None) -> list[tuple[str, str]]:
    """The journal fields of one structlog event (after the level, timestamp and exception processors), as
    (name, value) pairs; a name may repeat (journald keeps every value: a supervisor's ``stage_dead`` about the
    fitting stage has POSED_STAGE=supervisor and POSED_STAGE=fitting)."""
    event = dict(event_dict)
    out = [("MESSAGE", json.dumps(event, default=str)),
           ("PRIORITY", str(PRIORITIES.get(str(event.get("level", "info")).lower(), 6))),
           ("SYSLOG_IDENTIFIER", "posed")]
    name = str(event.pop("event", ""))
    out.append(("POSED_EVENT", name))
    for key in ("component", "stage"):
        if event.get(key) is not None:
            out.append(("POSED_STAGE", _text(event.pop(key))))
    robot = event.pop("robot", None) or robot
    if robot:
        out.append(("POSED_ROBOT", _text(robot)))
    event_id = event.pop("event_id", None)
    if event_id is None and name.startswith("fall_event"):
        event_id = event.pop("id", None)
    if event_id is not None:
        out.append(("POSED_EVENT_ID", _text(event_id)))
    event.pop("level", None)
    taken = {k for k, _ in out}
    for key, value in event.items():
        field = _field_name(key)
        if value is not None and field not in taken:
            out.append((field, _text(value)))
            taken.add(field)
    return out


class Sender:
    """The last structlog processor when journald is reachable: sends the entry, drops the event. When a send
    fails (journald restarting) the JSON line goes to ``fallback`` instead: nothing is lost."""

    def __init__(self, robot: str | None, fallback, send: Callable[..., None] | None = None) -> None:
        if send is None:
            from systemd import journal

            send = journal.sendv
        self.robot = robot
        self.fallback = fallback
        self._send = send

    def __call__(self, logger, method_name: str, event_dict: dict):
        entry = fields(event_dict, self.robot)
        try:
            self._send(*(f"{k}={v}" for k, v in entry))
        except OSError:
            try:
                self.fallback.write(entry[0][1] + "\n")
                self.fallback.flush()
            except (OSError, ValueError):
                pass
        raise structlog.DropEvent
