"""History query parameters as Zenoh parses them (issue 34 item 8): ';' separates them; the URL habit '&' (which
Zenoh leaves inside the first value) is read the same way instead of failing as "not a time"."""

from __future__ import annotations

import zenoh

from posed.daemon.bus.queries import parse_history_parameters


def test_semicolons_and_ampersands_give_the_same_selection():
    a = parse_history_parameters(zenoh.Parameters("since=1700000000;until=1700000100;limit=7"))
    b = parse_history_parameters(zenoh.Parameters("since=1700000000&until=1700000100&limit=7"))
    assert a == b == (1700000000.0, 1700000100.0, 7)


def test_the_documented_selectors_use_semicolons():
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    for doc in ("docs/daemon.md", "docs/falls.md"):
        text = (root / doc).read_text()
        assert "history/**?since=2h&" not in text and "history?since=..&" not in text, doc
