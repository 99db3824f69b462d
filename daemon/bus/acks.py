"""Acknowledgements put on ``posed/ROBOT/events/ack`` (interfaces.md section 4, docs/falls.md).

A payload is the event id as text, or JSON ``{"id": "<event id>"}`` (every message of the event so far) or
``{"id": ..., "state": "alarm"}`` (only that state's message), either with ``"by"``: who acknowledged (free
text, kept in the journal). Anyone on the bus can put anything there, so :func:`parse_ack_message` takes raw
bytes and accepts only a bounded, printable id: UTF-8, at most ``MAX_PAYLOAD_BYTES`` bytes, an id of at most
``MAX_ID_CHARS`` characters without whitespace or control characters inside, a state that is one of
:data:`falls.FALL_STATES`, and a ``by`` that is text of at most ``MAX_BY_CHARS`` printable characters (null
or blank: not said). Everything else raises :class:`BadAck` saying what is wrong (bounded, one line).
"""

from __future__ import annotations

import json
from dataclasses import dataclass

from posed.daemon.bus.inbound import payload_text, text_field
from posed.daemon.proc.throttle import shown
from posed.falls import FALL_STATES

MAX_PAYLOAD_BYTES = 4096
MAX_ID_CHARS = 128          # event ids are 32 hex digits (uuid4().hex)
MAX_BY_CHARS = 128          # a name, or user@host
EXPECTED = ('an event id, or JSON {"id": "<event id>"} or {"id": ..., "state": "<state>"}, optionally with '
            '"by": "<who>"')


class BadAck(ValueError):
    """An acknowledgement that cannot be used; the message says why (bounded, one line)."""


@dataclass(frozen=True)
class Ack:
    """One acknowledgement: ``state`` None acknowledges every message of event ``id`` so far; ``by`` who
    acknowledged (None: not said)."""

    id: str
    state: str | None = None
    by: str | None = None


def parse_ack_message(payload: bytes | str) -> Ack:
    """The acknowledgement in a payload; raises :class:`BadAck`."""
    raw = payload_text(payload, MAX_PAYLOAD_BYTES, BadAck).strip()
    state = by = None
    if raw.startswith("{"):
        try:
            obj = json.loads(raw)
        except (ValueError, RecursionError):    # RecursionError: nested deeper than Python's limit
            raise BadAck("payload starts with '{' but is not JSON") from None
        if not isinstance(obj, dict) or "id" not in obj:
            raise BadAck('JSON payload without an "id"')
        event_id = obj["id"] if isinstance(obj["id"], str) else json.dumps(obj["id"])
        state = obj.get("state")
        if state is not None and state not in FALL_STATES:
            raise BadAck(f"state {shown(str(state))!r} is not one of: {', '.join(FALL_STATES)}")
        by = _by(obj.get("by"))
    else:
        event_id = raw
    event_id = event_id.strip()
    if not event_id:
        raise BadAck("empty event id")
    if len(event_id) > MAX_ID_CHARS:
        raise BadAck(f"event id of {len(event_id)} characters is too long (at most {MAX_ID_CHARS})")
    if not event_id.isprintable() or any(c.isspace() for c in event_id):
        raise BadAck("event id holds whitespace or control characters")
    return Ack(event_id, state, by)


def _by(value) -> str | None:
    """The ``by`` of an acknowledgement: None when absent, null or blank; raises :class:`BadAck` when it is not
    bounded printable text."""
    return None if value is None else text_field(value, "by", MAX_BY_CHARS, BadAck, "who acknowledged")
