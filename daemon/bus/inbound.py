"""What anyone on the bus may put where the daemon listens (acknowledgements, the robot's camera pose) or ask it
(query parameters): raw bytes read as bounded text before any parsing, bounded printable text fields, and a
query's parameters. Each raises the caller's own error
type (``bad``: a ValueError subclass) with a one-line message saying what is wrong."""

from __future__ import annotations

from collections.abc import Callable


def payload_text(payload: bytes | str, max_bytes: int, bad: Callable[[str], Exception], expected: str = "") -> str:
    """A payload as UTF-8 text of at most ``max_bytes`` bytes; raises ``bad(message)`` (ending with "; expected
    ``expected``" when given)."""
    if isinstance(payload, str):
        payload = payload.encode("utf-8", "surrogatepass")
    suffix = f"; expected {expected}" if expected else ""
    if len(payload) > max_bytes:
        raise bad(f"payload of {len(payload)} bytes, more than {max_bytes}{suffix}")
    try:
        return payload.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise bad(f"payload is not UTF-8 text (byte {exc.start}){suffix}") from None


def text_field(value, key: str, max_chars: int, bad: Callable[[str], Exception], what: str = "") -> str | None:
    """A free-text field ``key``: text of at most ``max_chars`` printable characters once stripped (None when
    blank); raises ``bad(message)``, naming ``what`` it is when the value is not text."""
    if not isinstance(value, str):
        raise bad(f'"{key}" must be text{f" ({what})" if what else ""}, not {type(value).__name__}')
    value = value.strip()
    if len(value) > max_chars:
        raise bad(f'"{key}" of {len(value)} characters is too long (at most {max_chars})')
    if not value.isprintable():
        raise bad(f'"{key}" holds control characters')
    return value or None


def query_values(params, keys: tuple[str, ...]) -> dict[str, str]:
    """The values of ``keys`` among a query's parameters (anything with ``get(key)``, or None). Zenoh separates
    parameters with ``;``; a URL habit (``since=2h&limit=50``) reaches the daemon as one value
    (``since="2h&limit=50"``), which is split too rather than read as one odd value. Other keys found that way
    are kept as well (the caller ignores or rejects them)."""
    found: dict[str, str] = {}
    for key in keys:
        v = params.get(key) if params is not None else None
        if v is None:
            continue
        head, *rest = str(v).split("&")
        found.setdefault(key, head)
        for part in rest:
            k, _, val = part.partition("=")
            found.setdefault(k.strip(), val)
    return found
