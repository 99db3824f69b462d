"""Property-based fuzzing of config loading (``posed run --config FILE --set KEY=VALUE --source URI``):
whatever the file, the overrides and the source hold, loading gives a ``Config`` or a ``ConfigError`` whose
every problem names its key path (exit 78), never another exception."""

from __future__ import annotations

import dataclasses
import typing

import pytest
import yaml
from hypothesis import given
from hypothesis import strategies as st

from posed.daemon.config import Config, ConfigError, load_config
from tests.fuzz.strategies import FUZZ, deep_nesting


def _key_paths(cls, prefix: str = "") -> list[str]:
    hints = typing.get_type_hints(cls)
    out = []
    for f in dataclasses.fields(cls):
        if dataclasses.is_dataclass(hints[f.name]):
            out += _key_paths(hints[f.name], f"{prefix}{f.name}.")
        else:
            out.append(f"{prefix}{f.name}")
    return out


KEYS = _key_paths(Config)
SECTIONS = sorted({k.split(".")[0] for k in KEYS})
yaml_scalars = st.one_of(st.none(), st.booleans(), st.integers(), st.integers(-(10**40), 10**40),
                         st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=30))
yaml_values = st.recursive(yaml_scalars, lambda inner: st.one_of(
    st.lists(inner, max_size=4), st.dictionaries(st.one_of(st.text(max_size=8), st.sampled_from(KEYS)), inner,
                                                 max_size=4)), max_leaves=12)


def _nest(assignments: list[tuple[str, object]]) -> dict:
    """A config mapping setting each dotted key (real ones mostly, so the checks below the top are reached)."""
    data: dict = {}
    for key, value in assignments:
        node = data
        parts = key.split(".")
        for part in parts[:-1]:
            child = node.get(part)
            if not isinstance(child, dict):
                child = node[part] = {}
            node = child
        node[parts[-1]] = value
    return data


config_mapping = st.lists(st.tuples(st.one_of(st.sampled_from(KEYS), st.sampled_from(SECTIONS), st.text(max_size=10)),
                                    yaml_values), max_size=8).map(_nest)
config_text = st.one_of(
    config_mapping.map(lambda d: yaml.safe_dump(d, allow_unicode=True)),
    st.text(max_size=300),
    st.lists(st.sampled_from(["a: &x [1, 2]", "b: *x", "pipeline: {", "  target_fps: 5", "? [1]: 2", "%YAML 1.1",
                              "---", "...", "!!python/object:os.system {}", "zenoh:\n  listen: tls/", "\t- x",
                              "pipeline:\n  target_fps: .inf", "robot_id: !!binary aGk=", "x: 1\nx: 2"]),
             max_size=6).map("\n".join),
)
override = st.one_of(st.builds(lambda k, v: f"{k}={v}", st.sampled_from(KEYS), st.text(max_size=20)),
                     st.text(max_size=30))
source = st.one_of(st.none(), st.text(max_size=40),
                   st.builds(lambda s, r: f"{s}:{r}", st.sampled_from(["file", "v4l2", "realsense", "http", ""]),
                             st.text(max_size=40)))


def _load(path, overrides, src) -> None:
    try:
        cfg = load_config(path, overrides=overrides, source=src)
    except ConfigError as exc:
        assert exc.problems, "a ConfigError must list at least one problem"
        for p in exc.problems:
            assert isinstance(p.path, str) and isinstance(p.message, str) and p.message
        return
    assert isinstance(cfg, Config)


@FUZZ
@given(text=config_text, overrides=st.lists(override, max_size=3), src=source)
def test_any_config_text_loads_or_lists_its_problems(tmp_path_factory, text, overrides, src):
    path = tmp_path_factory.mktemp("cfg") / "config.yaml"
    path.write_text(text, encoding="utf-8", errors="surrogatepass")
    _load(path, overrides, src)


@FUZZ
@given(raw=st.binary(max_size=300))
def test_any_config_bytes_load_or_list_their_problems(tmp_path_factory, raw):
    path = tmp_path_factory.mktemp("cfgb") / "config.yaml"
    path.write_bytes(raw)
    _load(path, [], None)


@pytest.mark.parametrize("depth", [1_100])
def test_deeply_nested_yaml_is_a_config_error(tmp_path, depth):
    """Found by fuzzing: YAML nested deeper than Python's recursion limit raised RecursionError (a
    traceback, exit 1) from the file and from --set; now a ConfigError (exit 78)."""
    path = tmp_path / "config.yaml"
    path.write_text("robot_id: " + deep_nesting(depth))
    with pytest.raises(ConfigError, match="nested too deeply"):
        load_config(path)
    with pytest.raises(ConfigError, match="robot_id"):
        load_config(None, overrides=[f"robot_id={deep_nesting(depth)}"])
