"""daemon.logs: lines go to the stdout of the moment they are written."""

import io
import json
import sys
from pathlib import Path

import pytest
import structlog

from posed.daemon import logs


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


# --- journald (daemon.journald) -------------------------------------------------------------------------

def _stream_of(path):
    """A real file as the process's stdout would be when systemd connects it to the journal."""
    import os

    fh = open(path, "w")
    st = os.fstat(fh.fileno())
    return fh, f"{st.st_dev}:{st.st_ino}"


def test_journald_is_reachable_only_through_its_stream_and_socket(tmp_path):
    import socket

    from posed.daemon import journald

    out, stream_id = _stream_of(tmp_path / "stream")
    other, other_id = _stream_of(tmp_path / "other")
    sock_path = str(tmp_path / "journal.sock")
    with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM) as sock:
        sock.bind(sock_path)
        assert journald.reachable({"JOURNAL_STREAM": stream_id}, sock_path, streams=[out])
        assert not journald.reachable({"JOURNAL_STREAM": other_id}, sock_path, streams=[out])   # redirected
        assert not journald.reachable({}, sock_path, streams=[out])                           # not systemd
        assert not journald.reachable({"JOURNAL_STREAM": "garbage"}, sock_path, streams=[out])
    assert not journald.reachable({"JOURNAL_STREAM": stream_id}, str(tmp_path / "none.sock"), streams=[out])
    out.close()
    other.close()


def test_journal_fields_of_structlog_events(monkeypatch):
    """What the configured structlog pipeline hands to ``systemd.journal.sendv``: PRIORITY from the level,
    POSED_STAGE, POSED_ROBOT, the fall event id, every other key; MESSAGE is the JSON line."""
    from systemd import journal

    sent = []
    monkeypatch.setattr(journal, "sendv", lambda *items: sent.append(items))
    logs.configure("debug", "journal", robot="kitchen")
    logs.get("publisher").info("fall_event", id="ab12", state="alarm", confidence=0.9)
    logs.get("fitting").error("fit_failed", seq=7, error="boom")
    logs.get("supervisor").warning("stage_dead", stage="fitting", restart_in_s=0)
    logs.get("publisher").debug("hook_retry", event_id="cd34", argv=["/bin/x", "a b"])
    entries = []
    for items in sent:
        entry: dict[str, list[str]] = {}
        for item in items:
            key, _, value = item.partition("=")
            entry.setdefault(key, []).append(value)
        entries.append(entry)
    fall, failed, dead, hook = entries
    assert fall["PRIORITY"] == ["6"] and fall["POSED_STAGE"] == ["publisher"] and fall["POSED_ROBOT"] == ["kitchen"]
    assert fall["POSED_EVENT"] == ["fall_event"] and fall["POSED_EVENT_ID"] == ["ab12"]
    assert fall["POSED_STATE"] == ["alarm"] and fall["POSED_CONFIDENCE"] == ["0.9"]
    assert fall["SYSLOG_IDENTIFIER"] == ["posed"]
    message = json.loads(fall["MESSAGE"][0])
    assert (message["event"], message["id"], message["level"]) == ("fall_event", "ab12", "info")
    assert failed["PRIORITY"] == ["3"] and failed["POSED_STAGE"] == ["fitting"] and failed["POSED_SEQ"] == ["7"]
    assert dead["PRIORITY"] == ["4"] and sorted(dead["POSED_STAGE"]) == ["fitting", "supervisor"]
    assert hook["PRIORITY"] == ["7"] and hook["POSED_EVENT_ID"] == ["cd34"]
    assert json.loads(hook["POSED_ARGV"][0]) == ["/bin/x", "a b"]
    assert all(k.isupper() and len(k) <= 64 for e in entries for k in e)
    logs.configure("info", "json")


def test_a_failed_journal_send_falls_back_to_a_json_line():
    from posed.daemon import journald

    def refuse(*items):
        raise ConnectionRefusedError("journald is restarting")

    out = io.StringIO()
    sender = journald.Sender("r1", fallback=out, send=refuse)
    with pytest.raises(structlog.DropEvent):          # nothing else is printed
        sender(None, "info", {"event": "stats", "component": "supervisor", "fps": 10.0, "level": "info"})
    assert json.loads(out.getvalue()) == {"event": "stats", "component": "supervisor", "fps": 10.0,
                                          "level": "info"}


def test_journald_when_reachable_else_json_lines(tmp_path):
    """A process whose stdout is the journal stream: with journald (its socket exists) the event reaches the
    journal with its fields, read back with systemd.journal.Reader; without it, JSON lines on stdout."""
    import os
    import subprocess
    import sys
    import uuid

    from posed.daemon import journald

    tag = uuid.uuid4().hex
    out_path = tmp_path / "stdout"
    code = ("import os, sys; from daemon import logs; "
            "st = os.fstat(sys.stdout.fileno()); os.environ['JOURNAL_STREAM'] = f'{st.st_dev}:{st.st_ino}'; "
            f"logs.configure('info', 'auto', robot='jr'); logs.get('fitting').warning('journal_test', tag='{tag}')")
    with open(out_path, "w") as out:
        subprocess.run([sys.executable, "-c", code], stdout=out, check=True, timeout=60,
                       cwd=Path(__file__).resolve().parents[2])
    if os.path.exists(journald.SOCKET):
        from systemd import journal

        reader = journal.Reader()
        reader.add_match(POSED_TAG=tag)
        found = []
        for _ in range(50):
            found = list(reader)
            if found:
                break
            import time

            time.sleep(0.1)
        assert found, "the entry did not reach journald"
        e = found[0]
        assert (e["POSED_STAGE"], e["POSED_ROBOT"], e["PRIORITY"]) == ("fitting", "jr", 4)
        assert out_path.read_text() == ""
    else:
        line = json.loads(out_path.read_text())
        assert (line["event"], line["component"], line["tag"], line["level"]) == (
            "journal_test", "fitting", tag, "warning")


PAUSED_READER_CHILD = r"""
import sys, time
from posed.daemon import logs
logs.configure("info", "json")
log = logs.get("flood")
t0 = time.monotonic()
for i in range(20000):
    log.info("line", i=i, pad="y" * 200)
print(f"done {time.monotonic() - t0:.2f}", file=sys.stderr, flush=True)
sys.stdin.readline()                      # the reader is back
log.info("end")
assert logs.STDOUT.wait_drained(60.0)
"""


def test_a_paused_reader_never_stops_the_writer():
    """A log reader that stops reading (a paused ``less``): 20000 lines (5 MB, 80 pipe buffers) are logged
    without waiting; what does not fit the spill queue is dropped and counted, the rest comes in order once
    the reader is back, then a line saying how many were dropped."""
    import subprocess

    root = Path(__file__).resolve().parents[2]
    child = subprocess.Popen([sys.executable, "-c", PAUSED_READER_CHILD], cwd=root, stdin=subprocess.PIPE,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        done = child.stderr.readline()        # nobody reads stdout meanwhile; before the fix: stuck at ~64 kB
        assert done.startswith("done"), done + child.stderr.read()
        child.stdin.write("go\n")
        child.stdin.flush()
        out = child.stdout.read()
        assert child.wait(timeout=60) == 0, child.stderr.read()
    finally:
        if child.poll() is None:
            child.kill()
    lines = [json.loads(x) for x in out.splitlines()]
    got = [x["i"] for x in lines if x.get("event") == "line"]
    assert got == sorted(got) and got[0] == 0 and len(got) < 20000        # in order; some dropped
    told = [x for x in lines if x.get("event") == "log_lines_dropped"]
    assert len(told) == 1 and told[0]["count"] == 20000 - len(got)
    assert lines[-1]["event"] == "end"
    assert len(out.encode()) > logs.SPILL_BYTES                            # the spill queue was used
