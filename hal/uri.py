"""Source URIs: ``realsense:``, ``realsense:SERIAL``, ``v4l2:/dev/videoN`` (or ``v4l2:N``), ``file:PATH``.

Any URI may end in a query of ``source`` keys, ``?key=value&key=value``: the fault-injection keys by their
short names (``drop``, ``stall_at``, ``stall_s``, ``disconnect_at``, ``disconnect_s``, ``corrupt_at``,
``seed``) and any other key of :class:`hal.config.SourceConfig` by its own name (``loop=true``,
``realtime=false``, ``fx=615``, ``width=1280`` ...). Example::

    file:/data/squat.mp4?realtime=false&drop=0.1&stall_at=20&stall_s=3&disconnect_at=40&corrupt_at=10
"""

from __future__ import annotations

import dataclasses
import os
import typing
from urllib.parse import parse_qsl

from posed.hal.config import SOURCE_TYPES, SourceConfig
from posed.hal.errors import SourceUnsupported

FAULT_KEYS = ("drop", "stall_at", "stall_s", "disconnect_at", "disconnect_s", "corrupt_at", "seed")
_HINTS = typing.get_type_hints(SourceConfig)
_FIELDS = {f.name: f for f in dataclasses.fields(SourceConfig)}
# Scheme -> the SourceConfig field that holds what follows "scheme:".
TARGET_FIELDS = {"realsense": "serial", "v4l2": "device", "file": "path"}
# Fields a URI query may not set: the scheme and the targets are the URI itself.
_NOT_IN_QUERY = ("type", *TARGET_FIELDS.values())


def parse_uri(uri: str, base: SourceConfig | None = None) -> SourceConfig:
    """The config of a source URI, starting from ``base`` (default: all defaults)."""
    base = base or SourceConfig()
    scheme, sep, rest = uri.partition(":")
    if not sep or scheme not in SOURCE_TYPES:
        raise SourceUnsupported(f"{uri!r} is not a source URI; use realsense:[SERIAL], v4l2:/dev/videoN or "
                                "file:PATH", uri)
    key = TARGET_FIELDS[scheme]
    if scheme == "v4l2" and not rest:
        raise SourceUnsupported("v4l2: needs a device, e.g. v4l2:/dev/video0 or v4l2:0", uri)
    if scheme == "file" and not rest:
        raise SourceUnsupported("file: needs a path, e.g. file:video.mp4", uri)
    return split_query(dataclasses.replace(base, type=scheme, **{key: rest}))


def split_query(config: SourceConfig) -> SourceConfig:
    """Move a ``?query`` left in ``path``/``device``/``serial`` (as ``--source`` puts it) into the fields.

    A file path that exists with its ``?`` is taken as it is.
    """
    key = TARGET_FIELDS.get(config.type)
    if key is None:
        return config
    value = getattr(config, key)
    if "?" not in value or (key == "path" and os.path.exists(value)):
        return config
    head, _, query = value.partition("?")
    changes: dict[str, typing.Any] = {key: head}
    for name, raw in parse_qsl(query, keep_blank_values=True, strict_parsing=False):
        field = f"fault_{name}" if name in FAULT_KEYS else name
        if field not in _FIELDS or field in _NOT_IN_QUERY:
            raise SourceUnsupported(
                f"unknown option {name!r} in the source URI; valid: {', '.join(FAULT_KEYS)} or a source.* key "
                f"({', '.join(sorted(set(_FIELDS) - set(_NOT_IN_QUERY)))})", value)
        changes[field] = _parse_value(name, raw, _HINTS[field], value)
        _check_limits(name, changes[field], _FIELDS[field].metadata, value)
    try:
        return dataclasses.replace(config, **changes)
    except ValueError as exc:
        raise SourceUnsupported(f"bad source URI options: {exc}", value) from exc


def _parse_value(name: str, raw: str, tp: type, uri: str) -> typing.Any:
    try:
        if tp is bool:
            low = raw.strip().lower()
            if low in ("1", "true", "yes", "on", ""):
                return True
            if low in ("0", "false", "no", "off"):
                return False
            raise ValueError(raw)
        return tp(raw)
    except ValueError:
        raise SourceUnsupported(f"URI option {name}={raw!r} is not a {tp.__name__}", uri) from None


def _check_limits(name: str, v: typing.Any, meta: typing.Mapping, uri: str) -> None:
    lo, hi = meta.get("range", (None, None))
    if isinstance(v, float) and v != v:
        raise SourceUnsupported(f"URI option {name}=nan is not a number", uri)
    if isinstance(v, (int, float)) and not isinstance(v, bool) and (
            (lo is not None and v < lo) or (hi is not None and v > hi)):
        raise SourceUnsupported(f"URI option {name}={v} is out of range [{lo}, {'inf' if hi is None else hi}]", uri)
    if meta.get("choices") and v not in meta["choices"]:
        raise SourceUnsupported(f"URI option {name}={v!r} is not one of: {', '.join(meta['choices'])}", uri)


def to_uri(config: SourceConfig) -> str:
    """A short display name of a source config (without its other options)."""
    if config.type == "realsense":
        return f"realsense:{config.serial}"
    if config.type == "v4l2":
        return f"v4l2:{config.device}"
    return f"{config.type}:{config.path}"
