"""Property-based fuzzing of source URIs (``--source``, ``posed record``, ``posed landmarks`` ...): any text
gives a ``SourceConfig`` whose options are within their documented ranges and choices, or a
``SourceUnsupported`` naming the problem; never another exception. The same text through the config loader
(``load_config(source=...)``) gives a Config or a ConfigError."""

from __future__ import annotations

import dataclasses

import pytest
from hypothesis import given
from hypothesis import strategies as st

from posed.daemon.config import ConfigError, load_config
from posed.hal.config import SourceConfig
from posed.hal.errors import SourceUnsupported
from posed.hal.uri import FAULT_KEYS, parse_uri
from tests.fuzz.strategies import FUZZ

FIELDS = {f.name: f for f in dataclasses.fields(SourceConfig)}
OPTION_NAMES = sorted({*FAULT_KEYS, *FIELDS})
values = st.one_of(st.text(max_size=12), st.integers(-10**6, 10**6).map(str),
                   st.floats(allow_nan=True, allow_infinity=True).map(repr),
                   st.sampled_from(["true", "false", "yes", "0", "1", "", "nan", "inf", "-inf", "1e309", "0x10"]))
query = st.lists(st.tuples(st.one_of(st.sampled_from(OPTION_NAMES), st.text(max_size=8)), values), max_size=5).map(
    lambda kv: "&".join(f"{k}={v}" for k, v in kv))
uris = st.one_of(
    st.text(max_size=80),
    st.builds(lambda scheme, target, q: f"{scheme}:{target}" + (f"?{q}" if q else ""),
              st.sampled_from(["file", "v4l2", "realsense", "http", "FILE", ""]),
              st.one_of(st.text(max_size=30), st.sampled_from(["/dev/video0", "0", "x.mp4", "/nonexistent/a?b"])),
              query),
)


def _within_limits(cfg: SourceConfig) -> None:
    for name, f in FIELDS.items():
        v = getattr(cfg, name)
        lo, hi = f.metadata.get("range", (None, None))
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            assert v == v, f"{name} is NaN"
            assert (lo is None or v >= lo) and (hi is None or v <= hi), f"{name}={v} outside [{lo}, {hi}]"
        if f.metadata.get("choices"):
            assert v in f.metadata["choices"], f"{name}={v!r}"


@FUZZ
@given(uri=uris)
def test_any_uri_is_parsed_within_limits_or_refused(uri):
    try:
        cfg = parse_uri(uri)
    except SourceUnsupported as exc:
        assert str(exc)
        return
    assert cfg.type in ("file", "v4l2", "realsense")
    _within_limits(cfg)


@pytest.fixture(scope="module")
def default_config(tmp_path_factory):
    """A minimal config file (every other key at its default; the full template takes 0.2 s to load)."""
    path = tmp_path_factory.mktemp("cfg") / "config.yaml"
    path.write_text("robot_id: fuzz\n")
    return path


@FUZZ
@given(uri=uris)
def test_any_source_argument_loads_or_lists_its_problems(default_config, uri):
    try:
        load_config(default_config, source=uri)
    except ConfigError as exc:
        assert exc.problems


NUMERIC = sorted(n for n in OPTION_NAMES if n in FAULT_KEYS or (
    n in FIELDS and n not in ("type", "path", "device", "serial") and isinstance(getattr(SourceConfig(), n), float)))


@FUZZ
@given(name=st.sampled_from(NUMERIC), value=st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr), st.sampled_from(["nan", "NaN", "inf", "-inf", "1e309"])))
def test_numeric_options_are_finite_and_within_range_or_refused(name, value):
    try:
        cfg = parse_uri(f"file:squat.mp4?{name}={value}")
    except SourceUnsupported as exc:
        assert name in str(exc)
        return
    _within_limits(cfg)
