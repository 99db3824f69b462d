"""posed's message contract: the name and version of every message posed publishes or answers with (and of
the two it takes: ``posed.ack``, ``posed.camera_mount``), and their JSON Schemas (draft 2020-12, shipped in ``client/schemas/``; docs/formats.md describes them).

Each message carries ``format`` (one of :data:`FORMATS`) and ``version``; a version changes only if a field
would have to change meaning — fields are added freely and never renamed or removed, so a reader of version 1
keeps working. ``validate`` needs the ``jsonschema`` package (a dependency of posed).
"""

from __future__ import annotations

import json
from functools import cache
from importlib import resources

VERSION = 1

# format -> schema file in client/schemas (the schema's $id is urn:posed:schema:<stem>:<version>)
FORMATS = {
    "posed.pose": "pose",                     # posed/ROBOT/pose
    "posed.landmarks_frame": "landmarks_frame",    # posed/ROBOT/landmarks
    "posed.status": "status",                 # posed/ROBOT/status
    "posed.fall_event": "fall_event",         # posed/ROBOT/events/fall and events/history/** replies
    "posed.state": "state",                   # reply to posed/ROBOT/state
    "posed.event_history": "event_history",   # reply to the bare key posed/ROBOT/events/history
    "posed.ack": "ack",                       # what a receiver puts on posed/ROBOT/events/ack
    "posed.error": "error",                   # an error reply to a query
    "posed.camera_mount": "camera_mount",     # what the robot's software puts on posed/ROBOT/camera/mount
    "posed.privacy": "privacy",               # reply to a query on posed/ROBOT/privacy/pause
}
FIT_RESULT = "fit_result"                     # `posed fit` output and the core of posed.pose (no format field)
SCHEMA_NAMES = (*FORMATS.values(), FIT_RESULT)


@cache
def schema(name: str) -> dict:
    """The JSON Schema by file stem (``pose``, ``status``, ... ``fit_result``) or by format (``posed.pose``)."""
    stem = FORMATS.get(name, name)
    if stem not in SCHEMA_NAMES:
        raise KeyError(f"no schema {name!r}; known: {', '.join(sorted([*FORMATS, FIT_RESULT]))}")
    return json.loads(resources.files("posed.client").joinpath("schemas", f"{stem}.json").read_text())


@cache
def _registry():
    from referencing import Registry, Resource

    return Registry().with_resources(
        (schema(stem)["$id"], Resource.from_contents(schema(stem))) for stem in SCHEMA_NAMES)


@cache
def validator(name: str):
    """A ``jsonschema`` Draft 2020-12 validator for one schema (its references to the others resolved)."""
    from jsonschema import Draft202012Validator

    return Draft202012Validator(schema(name), registry=_registry(),
                                format_checker=Draft202012Validator.FORMAT_CHECKER)


def validate(obj, name: str | None = None) -> None:
    """Raise ``jsonschema.ValidationError`` when ``obj`` does not follow its schema (``name``, default: the
    schema of ``obj["format"]``)."""
    if name is None:
        fmt = obj.get("format") if isinstance(obj, dict) else None
        if fmt not in FORMATS:
            raise ValueError(f"format {fmt!r} is not one of posed's: {', '.join(FORMATS)}")
        name = fmt
    validator(name).validate(obj)


def errors(obj, name: str | None = None) -> list[str]:
    """Every problem of ``obj`` against its schema, one line each with its JSON path (empty: valid)."""
    try:
        name = name or obj["format"]
        v = validator(name)
    except (KeyError, TypeError) as exc:
        return [f"$: no known format ({exc})"]
    return [f"{e.json_path}: {e.message}" for e in sorted(v.iter_errors(obj), key=lambda e: list(e.path))]
