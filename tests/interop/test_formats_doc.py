"""docs/formats.md is the contract: each shipped JSON Schema has its section there, whose table lists exactly the
schema's fields; and each schema is a valid draft 2020-12 schema."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from jsonschema import Draft202012Validator

from posed.client import contract

DOC = Path(__file__).resolve().parents[2] / "docs" / "formats.md"


def sections() -> dict[str, set[str]]:
    """schema stem -> the field names in the first column of its section's table."""
    out: dict[str, set[str]] = {}
    current = None
    for line in DOC.read_text().splitlines():
        if line.startswith("#"):
            m = re.search(r"\(schema `(\w+)\.json`\)", line)
            current = m.group(1) if m else None
            if current:
                out[current] = set()
        elif current and (m := re.match(r"\| `(\w+)` \|", line)):
            out[current].add(m.group(1))
    return out


def test_every_schema_has_a_section():
    assert set(sections()) == set(contract.SCHEMA_NAMES)


@pytest.mark.parametrize("name", contract.SCHEMA_NAMES)
def test_the_section_lists_exactly_the_schema_fields(name):
    schema = contract.schema(name)
    Draft202012Validator.check_schema(schema)
    assert sections()[name] == set(schema["properties"]), name
    assert schema["$id"] == f"urn:posed:schema:{name}:{contract.VERSION}"


@pytest.mark.parametrize("fmt", contract.FORMATS)
def test_each_format_names_itself(fmt):
    schema = contract.schema(fmt)
    assert schema["title"] == fmt and schema["properties"]["format"] == {"const": fmt} or \
        schema["properties"]["format"].get("const") == fmt
    assert schema["properties"]["version"]["const"] == contract.VERSION
    assert f"`{fmt}`" in DOC.read_text()
