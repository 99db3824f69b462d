"""What a reader is told when the restored alarm came at once for a stepped clock, and when journal rows could not
be read, with the real ``posed run`` on a recording cut from a real fall (urfd_dev's urfd_04), killed -9 after
``on_floor``; the journal then holds a row that is not a message and the clock at the restart is 3 h behind the
one that journalled the fall (tests/daemon/test_alarm_journal_adversity_e2e.py's set-up):

* the alarm's ``restored.clock`` (``behind``) is in the fall-event schema and typed by the client
  (``Restored.clock``);
* `posed events` notes it on the alarm's line ("alarm raised at once: the clock was stepped back") and says on
  stderr, in one line, that a row could not be read, with the sqlite3 command that shows it (before: skipped
  silently); the command shows the damaged row;
* `posed web` (a real headless Chromium) notes it with the restored alarm, in the history."""

from __future__ import annotations

import json
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from posed.client import contract, restored
from posed.client.types import decode_event
from posed.commands._child import free_endpoint
from tests.daemon import restore_util as ru
from tests.daemon.test_alarm_journal_adversity_e2e import _alarms, _clock_behind_and_a_bad_row
from tests.daemon.test_alarm_kept_e2e import Daemon, state_of, wait_for
from tests.viz.browser import Browser
from tests.viz.web_cli import posed_web

ROOT = Path(__file__).resolve().parents[2]
HISTORY = "(document.getElementById('history') || {textContent: ''}).textContent"


def _posed_events(journal: Path, *args: str) -> subprocess.CompletedProcess:
    r = subprocess.run([sys.executable, "-m", "posed.cli", "events", "--journal", str(journal), *args], cwd=ROOT,
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    return r


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_a_clock_stepped_back_and_a_damaged_row_are_said_to_the_reader(tmp_path, shared_data):
    alarm_s = 20.0
    header, frames = ru.urfd04(shared_data)
    fall = ru.write(tmp_path / "fall.landmarks.jsonl", header,
                    frames + ru.held(frames[-1], frames[-1].t + 1 / 30, 10.0, seq0=len(frames), nobody=True))
    nobody = ru.write(tmp_path / "nobody.landmarks.jsonl", header, ru.held(frames[0], 0.0, 90.0, nobody=True))
    state = tmp_path / "state"
    first = Daemon(tmp_path / "run1", state, fall, f"falls.alarm_after_s={alarm_s}")
    try:
        wait_for(state_of(state, "on_floor"), 90, "on_floor", first)
    finally:
        first.kill9()
    _clock_behind_and_a_bad_row(state / "events.sqlite3")
    endpoint = free_endpoint()
    second = Daemon(tmp_path / "run2", state, nobody, f"falls.alarm_after_s={alarm_s}",
                    f'zenoh.listen=["{endpoint}"]', "robot_id=clock")
    web = browser = None
    try:
        wait_for(lambda: _alarms(state), 60, "the restored alarm", second)
        journal = state / "events.sqlite3"

        # the client and the schema
        listed = json.loads(_posed_events(journal, "--json").stdout)
        (alarm,) = [decode_event(e) for e in listed["events"] if e["state"] == "alarm"]
        assert restored(alarm) is not None and restored(alarm).clock == "behind", alarm.extra
        contract.validate(alarm.to_json(), "fall_event")
        bad = json.loads(json.dumps(alarm.to_json()))
        bad["restored"]["clock"] = "late"
        assert contract.errors(bad, "fall_event"), "the fall-event schema accepts any restored.clock"
        assert len(listed["unreadable_rows"]) == 1

        # posed events: the note on the alarm's line, one line on stderr for the damaged row
        r = _posed_events(journal)
        (line,) = [x for x in r.stdout.splitlines() if " alarm " in x]
        assert line.endswith("[taken back after a restart (was on_floor); alarm raised at once: the clock was "
                             "stepped back]"), line
        said = r.stderr.strip().splitlines()
        assert len(said) == 1 and "1 row(s) of the journal could not be read" in said[0], r.stderr
        command = said[0].split("look at them: ", 1)[1]
        assert command.startswith("sqlite3 ")
        shown = subprocess.run(shlex.split(command), capture_output=True, text=True, timeout=30)
        assert shown.returncode == 0 and "damaged" in shown.stdout and "{not json" in shown.stdout, shown

        # posed web: the history's restored alarm says why it came at once
        web, url = posed_web("clock", endpoint, 120)
        browser = Browser(tmp_path / "profile")
        browser.open(url)
        browser.wait_for(f"{HISTORY}.includes('the clock was stepped back')", 60, "the clock note in the history")
        assert "posed restarted during this fall" in browser.js(HISTORY)
        second.alive()
    finally:
        if browser is not None:
            browser.close()
        if web is not None:
            web.terminate()
            web.wait(10)
        code = second.stop()
    assert code == 0, second.err.read_text()[-2000:]
