"""Build frozen config dataclasses from plain YAML data, collecting every problem at once.

The section dataclasses live in the packages that own them (``hal.config``, ``landmarks.config``,
``fitting.config``, ``daemon.config.sections``) and use only the standard library: each field may carry
``dataclasses.field(metadata=...)`` with these keys

    doc      one-line meaning (shown in docs/config.md and in errors)
    unit     unit of the value ("s", "deg", "px", ...)
    range    (lo, hi) inclusive bounds for numbers; either may be None
    choices  tuple of the allowed values
    pattern  regular expression a string must match in full

Supported field types: bool, int, float, str, ``X | None``, ``tuple[X, ...]``, nested dataclasses and
``tuple[Dataclass, ...]`` (a YAML list of mappings). Unknown keys are rejected.
"""

from __future__ import annotations

import dataclasses
import re
import types
import typing
from typing import Any


@dataclasses.dataclass(frozen=True)
class ConfigProblem:
    """One thing wrong with a config: its dotted key path and what is wrong."""

    path: str
    message: str

    def __str__(self) -> str:
        return f"{self.path}: {self.message}" if self.path else self.message


class ConfigError(Exception):
    """Raised with every problem found; ``str()`` lists them one per line, each prefixed by the file.

    ``partial``: the config as far as it could be read (each wrong key at its default), or None when the file
    could not be read at all: what the start-up checks (``daemon.preflight.partial_problems``) still look at,
    so that one run lists every problem, not the schema's first and the rest after they are fixed."""

    def __init__(self, problems: list[ConfigProblem], origin: str = "config", partial: Any = None) -> None:
        self.problems = list(problems)
        self.origin = origin
        self.partial = partial
        super().__init__("\n".join(f"{origin}: {p}" for p in self.problems))


_MISSING = dataclasses.MISSING


def key_covers(key: str, name: str) -> bool:
    """Whether the dotted key path ``key`` is ``name``, lies inside it (``fitting.row_init`` in ``fitting``,
    ``hooks.on_event[1].argv`` in ``hooks.on_event``) or is a section holding it (``fitting`` for
    ``fitting.row_init``): a problem at ``key`` then concerns the setting ``name``."""
    return key == name or key.startswith((name + ".", name + "[")) or name.startswith(key + ".")


def _type_name(tp: Any) -> str:
    if tp is type(None):
        return "null"
    if isinstance(tp, type):
        return {"str": "string", "int": "integer", "float": "number", "bool": "boolean"}.get(
            tp.__name__, tp.__name__
        )
    return str(tp)


def _fmt(value: Any) -> str:
    return repr(value) if not isinstance(value, (dict, list)) else f"{type(value).__name__} {value!r}"


def build(cls: type, data: Any, path: str, problems: list[ConfigProblem]) -> Any:
    """Return an instance of dataclass ``cls`` from ``data`` (a mapping or None), appending problems.

    Fields that are missing take their defaults; a field that is wrong is reported and replaced by its
    default so that checking can go on and report everything.
    """
    if data is None:
        data = {}
    if not isinstance(data, dict):
        problems.append(ConfigProblem(path, f"expected a mapping of keys, got {_fmt(data)}"))
        data = {}
    hints = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls) if f.init}
    for key in data:
        if key not in fields:
            where = f"{path}.{key}" if path else str(key)
            valid = ", ".join(fields)
            problems.append(ConfigProblem(where, f"unknown key; valid keys here: {valid}"))
    kwargs: dict[str, Any] = {}
    for name, f in fields.items():
        where = f"{path}.{name}" if path else name
        if name in data:
            before = len(problems)
            value = _convert(hints[name], data[name], where, f.metadata, problems)
            if len(problems) == before or _read_in_part(hints[name], value):
                kwargs[name] = value
                continue
        if f.default is _MISSING and f.default_factory is _MISSING:  # type: ignore[misc]
            if name not in data:
                problems.append(ConfigProblem(where, "required key is missing"))
            kwargs[name] = _placeholder(hints[name])
    try:
        return cls(**kwargs)
    except (TypeError, ValueError) as exc:  # a cross-field check in __post_init__
        problems.extend(_cross_field_problems(str(exc), path, fields))
        return _as_read(cls, kwargs)


def _cross_field_problems(text: str, path: str, fields: dict) -> list[ConfigProblem]:
    """A section's ``__post_init__`` message, ``"key: what is wrong; key: ..."``, as problems at each key's
    path (``zenoh.connect``, not ``zenoh``), so that the start-up checks of the section's other keys still run
    (``preflight.partial_problems`` leaves out only what a problem names); a part naming no field of the
    section stays at the section's path."""
    keys: list[str] = []        # "" for text before any key
    texts: list[str] = []
    for part in text.split("; "):
        key, sep, what = part.partition(": ")
        if sep and key in fields:
            keys.append(key)
            texts.append(what)
        elif texts:                 # a "; " inside one key's message
            texts[-1] += "; " + part
        else:
            keys.append("")
            texts.append(part)
    return [ConfigProblem(f"{path}.{k}" if path and k else (k or path), t) for k, t in zip(keys, texts, strict=True)]


def _as_read(cls: type, kwargs: dict) -> Any:
    """An instance of ``cls`` holding ``kwargs`` (the rest at their defaults) whose cross-field check failed:
    only for the config a ``ConfigError`` carries (``partial``), so that the section's other keys are checked as
    written; never run."""
    obj = object.__new__(cls)
    for f in dataclasses.fields(cls):
        if f.name in kwargs:
            value = kwargs[f.name]
        elif f.default is not _MISSING:
            value = f.default
        elif f.default_factory is not _MISSING:  # type: ignore[misc]
            value = f.default_factory()  # type: ignore[misc]
        else:
            value = None
        object.__setattr__(obj, f.name, value)
    return obj


def _read_in_part(tp: Any, value: Any) -> bool:
    """A section (or a list of them) whose wrong keys ``build`` already set to their defaults: kept as read, so
    that the config the error carries (``ConfigError.partial``) has the section's other keys as written."""
    if dataclasses.is_dataclass(tp):
        return dataclasses.is_dataclass(value)
    args = typing.get_args(tp)
    return (typing.get_origin(tp) is tuple and len(args) == 2 and args[1] is Ellipsis
            and dataclasses.is_dataclass(args[0]) and isinstance(value, tuple)
            and all(dataclasses.is_dataclass(v) for v in value))


def _placeholder(tp: Any) -> Any:
    if dataclasses.is_dataclass(tp):
        return tp()
    return None


def _convert(tp: Any, value: Any, path: str, meta: Any, problems: list[ConfigProblem]) -> Any:
    origin = typing.get_origin(tp)
    if origin in (typing.Union, types.UnionType):
        args = typing.get_args(tp)
        if value is None and type(None) in args:
            return None
        non_none = [a for a in args if a is not type(None)]
        if len(non_none) == 1:
            return _convert(non_none[0], value, path, meta, problems)
        problems.append(ConfigProblem(path, f"unsupported union type {tp}"))
        return None
    if dataclasses.is_dataclass(tp):
        return build(tp, value, path, problems)
    if origin is tuple:
        args = typing.get_args(tp)
        if not isinstance(value, (list, tuple)):
            problems.append(ConfigProblem(path, f"expected a list, got {_fmt(value)}"))
            return None
        if len(args) == 2 and args[1] is Ellipsis:
            items = [_convert(args[0], v, f"{path}[{i}]", {}, problems) for i, v in enumerate(value)]
        else:
            if len(value) != len(args):
                problems.append(ConfigProblem(path, f"expected a list of {len(args)} items, got {len(value)}"))
                return None
            items = [_convert(a, v, f"{path}[{i}]", {}, problems) for i, (a, v) in enumerate(zip(args, value, strict=True))]
        result = tuple(items)
        _check_meta(result, path, meta, problems)
        return result
    if tp is bool:
        if not isinstance(value, bool):
            problems.append(ConfigProblem(path, f"{_fmt(value)} is not a boolean (use true or false)"))
            return None
        return value
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            problems.append(ConfigProblem(path, f"{_fmt(value)} is not an integer"))
            return None
    elif tp is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            problems.append(ConfigProblem(path, f"{_fmt(value)} is not a number"))
            return None
        value = float(value)
        if value != value:
            problems.append(ConfigProblem(path, "NaN is not allowed"))
            return None
    elif tp is str:
        if isinstance(value, bool):         # YAML 1.1 reads a bare off/on/no/yes as false/true
            word = _yaml_word(value, meta)
            if word is None:
                problems.append(ConfigProblem(path, f"{_fmt(value)} is not a string (YAML reads a bare off, on, no "
                                                    "or yes as a boolean: quote the word, e.g. \"off\")"))
                return None
            value = word
        if not isinstance(value, str):
            problems.append(ConfigProblem(path, f"{_fmt(value)} is not a string"))
            return None
    else:
        problems.append(ConfigProblem(path, f"unsupported field type {_type_name(tp)}"))
        return None
    _check_meta(value, path, meta, problems)
    return value


def _yaml_word(value: bool, meta: Any) -> str | None:
    """The choice a bare YAML ``off``/``on`` meant, when the key has that choice (``source.infrared: off``);
    None when it has not."""
    word = "on" if value else "off"
    choices = meta.get("choices") if meta else None
    return word if choices is not None and word in choices else None


def _check_meta(value: Any, path: str, meta: Any, problems: list[ConfigProblem]) -> None:
    choices = meta.get("choices") if meta else None
    if choices is not None:
        values = value if isinstance(value, tuple) else (value,)
        for v in values:
            if v not in choices:
                problems.append(
                    ConfigProblem(path, f"{v!r} is not one of: {', '.join(str(c) for c in choices)}")
                )
    rng = meta.get("range") if meta else None
    if rng is not None and isinstance(value, (int, float)):
        lo, hi = rng
        if (lo is not None and value < lo) or (hi is not None and value > hi):
            unit = f" {meta['unit']}" if meta.get("unit") else ""
            lo_s = "-inf" if lo is None else lo
            hi_s = "inf" if hi is None else hi
            problems.append(ConfigProblem(path, f"{value!r} is out of range [{lo_s}, {hi_s}]{unit}"))
    pattern = meta.get("pattern") if meta else None
    if pattern is not None and isinstance(value, str) and not re.fullmatch(pattern, value):
        problems.append(ConfigProblem(path, f"{value!r} does not match the pattern {pattern}"))


def apply_override(data: dict, assignment: str) -> ConfigProblem | None:
    """Apply one ``key.path=value`` override (value parsed as YAML) to a raw config mapping in place."""
    import yaml

    if "=" not in assignment:
        return ConfigProblem("--set", f"{assignment!r} is not of the form key.path=value")
    key, _, raw = assignment.partition("=")
    parts = [p for p in key.strip().split(".") if p]
    if not parts:
        return ConfigProblem("--set", f"{assignment!r} has an empty key")
    try:
        if raw.strip():
            node = yaml.compose(raw, Loader=yaml.SafeLoader)
            if node is not None:
                _check_aliases(node)
        value = yaml.safe_load(raw) if raw.strip() else ""
    except ConfigError as exc:
        return ConfigProblem(key, f"value {raw[:80]!r}: {exc.problems[0].message}")
    except (yaml.YAMLError, RecursionError) as exc:
        return ConfigProblem(key, f"value {raw[:80]!r} is not valid YAML: {exc}")
    node = data
    for part in parts[:-1]:
        child = node.get(part)
        if child is None:
            child = node[part] = {}
        if not isinstance(child, dict):
            return ConfigProblem(key, f"{part!r} is not a section")
        node = child
    node[parts[-1]] = value
    return None


def describe(cls: type, prefix: str = "") -> list[tuple[str, str, str, str, str]]:
    """Rows (key path, type, default, unit/range/choices, doc) for every leaf field, for docs/config.md."""
    rows = []
    hints = typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        path = f"{prefix}{f.name}"
        tp = hints[f.name]
        if dataclasses.is_dataclass(tp):
            rows.extend(describe(tp, path + "."))
            continue
        default = f.default if f.default is not _MISSING else (
            f.default_factory() if f.default_factory is not _MISSING else ""  # type: ignore[misc]
        )
        meta = f.metadata or {}
        limits = []
        if meta.get("unit"):
            limits.append(meta["unit"])
        if meta.get("range"):
            lo, hi = meta["range"]
            limits.append(f"[{'-inf' if lo is None else lo}, {'inf' if hi is None else hi}]")
        if meta.get("choices"):
            limits.append("one of " + ", ".join(str(c) for c in meta["choices"]))
        if meta.get("pattern"):
            limits.append(f"pattern {meta['pattern']}")
        # a nested type by its own name (``tuple[HookConfig, ...]``), not its module path
        type_s = re.sub(r"\b(?:[a-z_]\w*\.)+([A-Z]\w*)", r"\1", str(tp)) if not isinstance(tp, type) else tp.__name__
        rows.append((path, type_s, repr(default), "; ".join(limits), meta.get("doc", "")))
    return rows


MAX_CONFIG_BYTES = 1 << 20     # the documented config.yaml is about 20 kB


def read_config_bytes(path) -> bytes:
    """The bytes of a config file, read with a bound: a file larger than MAX_CONFIG_BYTES (or /dev/zero) is
    a ConfigError, not read whole. Raises OSError as ``open`` does."""
    with open(path, "rb") as fh:
        raw = fh.read(MAX_CONFIG_BYTES + 1)
    if len(raw) > MAX_CONFIG_BYTES:
        raise ConfigError([ConfigProblem("", f"the file is larger than {MAX_CONFIG_BYTES} bytes: not a posed "
                                             "config (config.yaml is about 20 kB)")], str(path))
    return raw


def parse_yaml(raw: bytes) -> tuple[Any, list[ConfigProblem]]:
    """The YAML document in ``raw`` (UTF-8) and the problems that do not stop reading it (duplicate keys:
    the last one would silently win, so each is reported with its key path and both lines).

    Raises ConfigError for text that is not UTF-8 or not YAML (nothing more can be checked then)."""
    import yaml

    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw[: exc.start].count(b"\n") + 1
        raise ConfigError([ConfigProblem("", f"the file is not UTF-8 text: byte 0x{raw[exc.start]:02x} at line "
                                             f"{line}; save it as UTF-8 (e.g. iconv -f latin1 -t utf-8)")]) from None
    try:
        node = yaml.compose(text, Loader=yaml.SafeLoader)
        if node is not None:
            _check_aliases(node)               # before anything expands them: nothing may grow without bound
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ConfigError([ConfigProblem("", f"not valid YAML: {exc}")]) from exc
    except RecursionError:
        raise ConfigError([ConfigProblem("", "not a config: lists or mappings nested too deeply")]) from None
    problems: list[ConfigProblem] = []
    if node is not None:
        _duplicates(node, "", problems, set())
    return data, problems


MAX_EXPANDED_NODES = 100_000    # the whole documented config is ~300 nodes; a "billion laughs" is 10^9


def _check_aliases(root: Any) -> None:
    """Refuse a document whose aliases refer to themselves (``a: &a [*a]``: infinite) or expand to more than
    MAX_EXPANDED_NODES values (an alias bomb), counted on the composed graph, where an alias is one node
    shared, in time linear in the text."""
    import yaml

    sizes: dict[int, int] = {}
    on_path: set[int] = set()

    def size(node) -> int:
        key = id(node)
        if key in sizes:
            return sizes[key]
        if key in on_path:
            raise ConfigError([ConfigProblem("", f"a YAML alias at line {node.start_mark.line + 1} refers to the "
                                                 "list or mapping that holds it (an endless value); write the "
                                                 "value out instead of the alias")])
        on_path.add(key)
        if isinstance(node, yaml.MappingNode):
            n = 1 + sum(size(k) + size(v) for k, v in node.value)
        elif isinstance(node, yaml.SequenceNode):
            n = 1 + sum(size(v) for v in node.value)
        else:
            n = 1
        on_path.discard(key)
        if n > MAX_EXPANDED_NODES:
            raise ConfigError([ConfigProblem("", f"the YAML aliases expand to more than {MAX_EXPANDED_NODES} "
                                                 "values (an alias bomb?); a posed config needs a few hundred: "
                                                 "write the values out instead of nesting aliases")])
        sizes[key] = n
        return n

    size(root)


def _duplicates(node: Any, path: str, problems: list[ConfigProblem], seen_nodes: set[int]) -> None:
    import yaml

    if id(node) in seen_nodes:      # an alias: the node it names was checked where it was defined
        return
    seen_nodes.add(id(node))
    if isinstance(node, yaml.MappingNode):
        seen: dict[str, int] = {}
        for key, value in node.value:
            name = str(key.value) if isinstance(key, yaml.ScalarNode) else "?"
            where = f"{path}.{name}" if path else name
            line = key.start_mark.line + 1
            if name in seen and name != "<<":
                problems.append(ConfigProblem(where, f"duplicate key (lines {seen[name]} and {line}); the last "
                                                     "one would win silently: remove one"))
            else:
                seen[name] = line
            _duplicates(value, where, problems, seen_nodes)
    elif isinstance(node, yaml.SequenceNode):
        for i, item in enumerate(node.value):
            _duplicates(item, f"{path}[{i}]", problems, seen_nodes)
