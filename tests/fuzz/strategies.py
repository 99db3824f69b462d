"""Shared hypothesis settings and strategies for fuzzing the parsers that take outside input."""

from __future__ import annotations

import json
import os

from hypothesis import HealthCheck, settings
from hypothesis import strategies as st

# Bounded: the machine is shared; each parser gets a few hundred inputs per run, no deadline (CI may be slow).
# Derandomized, so that CI runs the same inputs every time (a red run can be reproduced, never flaky);
# POSED_FUZZ_EXPLORE=1 draws new inputs on every run (to look for new failures before committing).
FUZZ = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow],
                derandomize=os.environ.get("POSED_FUZZ_EXPLORE") != "1")

# JSON-ish values: scalars including the awkward ones (huge ints, non-finite floats, odd unicode)
json_scalars = st.one_of(
    st.none(), st.booleans(), st.integers(), st.integers(min_value=-(10**30), max_value=10**30),
    st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=20),
)
json_values = st.recursive(json_scalars, lambda inner: st.one_of(
    st.lists(inner, max_size=6), st.dictionaries(st.text(max_size=8), inner, max_size=6)), max_leaves=30)


def json_line(obj) -> str:
    """``obj`` as one JSON line, NaN/Infinity written the way Python writes them (not JSON, but seen)."""
    return json.dumps(obj, allow_nan=True)


def deep_nesting(depth: int) -> str:
    """A JSON array nested ``depth`` deep (what a hostile writer puts on one line)."""
    return "[" * depth + "]" * depth
