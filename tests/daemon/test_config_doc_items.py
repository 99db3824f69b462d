"""docs/config.md lists the keys of each item of a list setting (hooks.on_event, falls.household)."""

import dataclasses
import typing

from posed.cli import main
from posed.daemon.config import Config


def _item_classes(cls, prefix=""):
    """Key path -> item dataclass of every ``tuple[Dataclass, ...]`` setting, found here independently."""
    out = {}
    hints = typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        tp = hints[f.name]
        args = typing.get_args(tp)
        if dataclasses.is_dataclass(tp):
            out.update(_item_classes(tp, f"{prefix}{f.name}."))
        elif typing.get_origin(tp) is tuple and args and dataclasses.is_dataclass(args[0]):
            out[f"{prefix}{f.name}"] = args[0]
    return out


def test_every_item_key_is_in_config_doc(capsys):
    assert main(["config", "doc"]) == 0
    text = capsys.readouterr().out
    items = _item_classes(Config)
    assert {"hooks.on_event", "falls.household"} <= set(items)
    for path, item in items.items():
        assert not any(dataclasses.is_dataclass(tp) for tp in typing.get_type_hints(item).values())  # flat items
        for key in (f"{path}[].{f.name}" for f in dataclasses.fields(item)):
            rows = [line for line in text.splitlines() if line.startswith(f"| `{key}` |")]
            assert len(rows) == 1, f"{key} is not a row of `posed config doc`"
            field = {f.name: f for f in dataclasses.fields(item)}[key.rsplit(".", 1)[1]]
            assert field.metadata.get("doc") and field.metadata["doc"] in rows[0], f"{key}: its doc is not in its row"


def test_item_rows_carry_default_unit_and_range(capsys):
    assert main(["config", "doc"]) == 0
    text = capsys.readouterr().out
    assert "| `hooks.on_event[].timeout_s` | float | `10.0` | s; [0.1, 3600.0] | kill after |" in text
    assert "| `hooks.on_event[].retries` | int | `2` | [0, 100] |" in text
    assert "| `falls.household[].name` | str | required | pattern " in text
    assert "| `falls.household[].height_m` | float | `1.65` | m; [0.9, 2.3] |" in text
