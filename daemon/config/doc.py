"""Render the documented default config (config.yaml) and the config reference (docs/config.md) from the
section dataclasses, so that every key is documented exactly once: in its field's metadata."""

from __future__ import annotations

import dataclasses
import json
import typing

from posed.daemon.config import Config

HEADER = """\
# posed configuration: the embedded default. Generated from the code by `posed config template`;
# docs/config.md has the same reference as a table. Every key may be left out (its default applies),
# unknown keys are rejected, and `posed config check FILE` lists every problem at once (exit 78).
# Override on the command line: --set section.key=value, --source URI.
"""


WHICH_FILE = """\
## Which config file a command reads

Every `posed` command that reads a configuration (`run`, `demo`, `watch`, `events`, `history`, `plot`,
`fit`, `landmarks`, `record`, `calibrate`, `models`, `warmup`, `config show`, the benchmarks) finds it the same
way, first match wins:

1. `--config FILE`;
2. the environment variable `POSED_CONFIG`;
3. `/etc/posed/config.yaml`, when it exists (the service's, written by `deploy/install.sh`);
4. the embedded default: built from the code, the same text as `posed config template` and the repository's
   `config.yaml` (an installed wheel needs no file).

`posed config check FILE` checks the file it is given. So on the robot, `posed watch`, `posed events`,
`posed events ack ID` and `posed history` reach the service with no option: its Zenoh endpoint comes from
`zenoh.listen` (a wildcard host such as 0.0.0.0 is reached at 127.0.0.1), its robot id from `robot_id`.

The state dir (events.sqlite3, history.sqlite3): `pipeline.state_dir` if set, else `$STATE_DIRECTORY`
(systemd's `StateDirectory=`, `/var/lib/posed` for the service), else `$XDG_STATE_HOME/posed`, else
`~/.local/state/posed`. The commands that only read it (`posed events`, `posed history`, `posed plot
history`, and `posed events ack` to complete an id and confirm the acknowledgement) open the service's
`/var/lib/posed` instead of that last default when the config in effect is `/etc/posed/config.yaml`, or when
only `/var/lib/posed` holds the file they read. Reading the service's files needs its permissions (`sudo`, or
`sudo -u posed`).

Times shown to people (`posed events`, `posed history`, `posed report`, `posed plot history`, `posed watch`) are
in the robot's time zone: `--tz ZONE` when given, else `$TZ`, else the zone `/etc/localtime` points at
(`timedatectl set-timezone`); there is no config key. `posed events --utc` and `posed history --utc` print UTC.

Upgrades: no config key has been renamed or removed since the first release, so an old
`/etc/posed/config.yaml` stays valid. The landmark models folder (`landmarks.models_dir`) must hold what this
posed runs (its manifest: this converter version, mediapipe's pinned TFLite files); an earlier posed's folder
is named by `posed config check` (exit 78) and at `posed run`'s start, which watches on with it until `posed
models fetch` converts the kept files again (no download)."""


def _yaml_value(value: typing.Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, tuple):
        return json.dumps(list(value)) if all(not dataclasses.is_dataclass(v) for v in value) else "[]"
    if isinstance(value, str):
        return json.dumps(value)
    return repr(value)


def _limits(meta: typing.Mapping) -> str:
    parts = []
    if meta.get("unit"):
        parts.append(meta["unit"])
    if meta.get("range"):
        lo, hi = meta["range"]
        parts.append(f"range {'-inf' if lo is None else lo}..{'inf' if hi is None else hi}")
    if meta.get("choices"):
        parts.append("one of: " + ", ".join(str(c) for c in meta["choices"]))
    if meta.get("pattern"):
        parts.append(f"pattern {meta['pattern']}")
    return "; ".join(parts)


def _item_default(f: dataclasses.Field) -> str:
    """``default V`` for an item key of a list setting; empty for a required key (its doc says so)."""
    if f.default is not dataclasses.MISSING:
        return f"default {_yaml_value(f.default)}"
    if f.default_factory is not dataclasses.MISSING:  # type: ignore[misc]
        return f"default {_yaml_value(f.default_factory())}"  # type: ignore[misc]
    return ""


def template() -> str:
    """config.yaml text: every section and key with its default, meaning, unit and range."""
    lines = [HEADER]
    hints = typing.get_type_hints(Config)
    for f in dataclasses.fields(Config):
        tp = hints[f.name]
        if not dataclasses.is_dataclass(tp):
            lines.append(f"# {f.metadata.get('doc', '')} ({_limits(f.metadata)})")
            lines.append(f"{f.name}: {_yaml_value(f.default)}\n")
            continue
        doc = (tp.__doc__ or "").strip().splitlines()[0]
        lines.append(f"# --- {f.name}: {doc}")
        lines.append(f"{f.name}:")
        section_hints = typing.get_type_hints(tp)
        default = f.default if f.default is not dataclasses.MISSING else tp()
        for sf in dataclasses.fields(tp):
            meta = sf.metadata or {}
            limits = _limits(meta)
            lines.append(f"  # {meta.get('doc', '')}" + (f" ({limits})" if limits else ""))
            stp = section_hints[sf.name]
            args = typing.get_args(stp)
            if args and dataclasses.is_dataclass(args[0]):
                item = args[0]
                lines.append("  # each item: " + ", ".join(
                    f"{x.name} ({'; '.join(p for p in (x.metadata.get('doc', ''), _item_default(x), _limits(x.metadata)) if p)})"
                    for x in dataclasses.fields(item)))
            lines.append(f"  {sf.name}: {_yaml_value(getattr(default, sf.name))}")
        lines.append("")
    return "\n".join(lines).rstrip() + "\n"


def reference() -> str:
    """docs/config.md text."""
    from posed.daemon.config.load import describe

    out = ["# Configuration reference", "",
           "Generated by `posed config doc` from the code (the same text as the comments of `config.yaml`).",
           "Load rules: `yaml.safe_load`, then frozen dataclasses per section; unknown keys are rejected; every",
           "problem is reported at once with its key path, the bad value and the valid choices or range.",
           "Keys wrong between themselves are rejected by every command:",
           "`fitting.row_init` above `row_max`, `video_row_init` above `video_row_max`, `visibility_drop` not",
           "below `visibility_full`; `source.reconnect_max_s` below `reconnect_initial_s`; `zenoh.mode` client",
           "with an empty `zenoh.connect`; a `zenoh.listen` or `zenoh.connect` entry that is not an endpoint",
           "such as tcp/127.0.0.1:7447; two `falls.household` members with the same name; a `web.token`",
           "shorter than 16 characters, or empty while `web.host` is not a loopback address.",
           "Each such problem is reported at the key it names (e.g. `zenoh.connect`), and the section's other",
           "keys are still checked.",
           "`posed config check FILE` and `posed run` exit 0 or 78 (EX_CONFIG); with a key wrong they still run",
           "the start-up checks (models, calibration file, hook programs, the native Zenoh config) on the rest",
           "of the file, so one run lists every problem (a check of a key already named is left out: it would",
           "be about that key's default). `--set key.path=value` (value parsed as YAML)",
           "and `--source URI` override the file.", "",
           *WHICH_FILE.splitlines(), "",
           "| key | type | default | unit / range / choices | meaning |", "|---|---|---|---|---|"]
    items = _item_classes(Config)
    for path, type_s, default, limits, doc in describe(Config):
        out.append(f"| `{path}` | {type_s} | `{default}` | {limits} | {doc} |".replace("|  |", "| |"))
        if path in items:
            out.extend(_item_rows(items[path], path + "[]."))
    return "\n".join(out) + "\n"


def _list_item(tp: typing.Any) -> typing.Any:
    """The item dataclass of a ``tuple[Dataclass, ...]`` field type, else None."""
    args = typing.get_args(tp)
    if typing.get_origin(tp) is tuple and len(args) == 2 and args[1] is Ellipsis and dataclasses.is_dataclass(args[0]):
        return args[0]
    return None


def _item_classes(cls: type, prefix: str = "") -> dict[str, type]:
    """Key path -> item dataclass of every list-of-mappings setting (``hooks.on_event``: HookConfig)."""
    out: dict[str, type] = {}
    hints = typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        tp = hints[f.name]
        if dataclasses.is_dataclass(tp):
            out.update(_item_classes(tp, f"{prefix}{f.name}."))
        elif _list_item(tp) is not None:
            out[f"{prefix}{f.name}"] = _list_item(tp)
    return out


def _item_rows(item: type, prefix: str) -> list[str]:
    """Rows of docs/config.md for the keys of each item of a list setting; a key with no default is required."""
    from posed.daemon.config.load import describe

    required = {f.name for f in dataclasses.fields(item)
                if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING}  # type: ignore[misc]
    rows = []
    for path, type_s, default, limits, doc in describe(item, prefix):
        default_s = "required" if path[len(prefix):] in required else f"`{default}`"
        rows.append(f"| `{path}` | {type_s} | {default_s} | {limits} | {doc} |".replace("|  |", "| |"))
    return rows
