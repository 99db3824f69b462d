"""daemon.logs: lines go to the stdout of the moment they are written."""

import io
import json
import sys

from daemon import logs


def test_a_replaced_stdout_gets_the_lines_and_a_closed_one_is_never_written(monkeypatch):
    first, second = io.StringIO(), io.StringIO()
    monkeypatch.setattr(sys, "stdout", first)
    logs.configure("info", "json")
    logs.get("test").info("one")
    first.close()                                   # e.g. the capture of an earlier test, now gone
    monkeypatch.setattr(sys, "stdout", second)
    logs.configure("info", "json")                  # same arguments: a no-op, as in every stage
    logs.get("test").info("two", n=2)
    line = json.loads(second.getvalue().strip().splitlines()[-1])
    assert (line["event"], line["n"], line["component"]) == ("two", 2, "test")


def test_an_explicit_stream_is_used():
    out = io.StringIO()
    logs.configure("info", "json", stream=out)
    logs.get("x").warning("w")
    assert json.loads(out.getvalue())["level"] == "warning"
    logs.configure("info", "json")


def test_stderr_given_at_configure_time_follows_later_replacements(monkeypatch):
    first, second = io.StringIO(), io.StringIO()
    monkeypatch.setattr(sys, "stderr", first)
    logs.configure("info", "json", stream=sys.stderr)   # what `posed record` does
    first.close()
    monkeypatch.setattr(sys, "stderr", second)
    logs.get("rec").info("after")
    assert json.loads(second.getvalue())["event"] == "after"
    logs.configure("info", "json")
