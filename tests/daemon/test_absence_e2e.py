"""The person not seen for longer than usual, end to end: the real ``posed run`` (supervisor, capture, fitting and
publisher processes, its own state dir) on a landmark recording cut from a real one (urfd_dev's urfd_04: its
first frame, a person standing), with a history file already holding 14 days in which the person was always
seen again within 30 minutes, and the last 5 hours watched with nobody in view (longer than the usual, which
falls.absence counts from this time of day to the return after the last outing that began within 2 h after it on
past days: at most 2.5 h here, plus the 1 h margin).

The recording first has nobody in view: the notice comes right after the start (``hooks.on_absent`` runs with
``POSED_ABSENT=absent`` and the ``posed.absence`` object on stdin; the status's ``presence`` says ``absent``);
then the person stands in view for 10 s: the hook runs again with ``POSED_ABSENT=back``. Without the history
(``falls.history_enabled`` false), or with ``falls.absence_enabled`` false, ``presence`` is null and no hook
runs."""

from __future__ import annotations

import json
import socket
import threading
import time
from pathlib import Path

import pytest

from posed.client import contract
from posed.daemon.timeparse import local_zone
from tests.daemon import restore_util as ru
from tests.daemon.replay_util import replay_to_end
from tests.daemon.test_absence_watch import USUAL_BOUND_S, expected_usual, fill_history

DAY = 86400.0
HOOK = """\
rec="$1"
body=$(cat)
echo "$POSED_ABSENT|$POSED_ABSENT_LAST_SEEN_UNIX|$POSED_ROBOT|$POSED_HOOK_ATTEMPT|$body" >> "$rec"
"""


def _set_up(tmp_path: Path, shared_data: Path) -> tuple[Path, Path, str, float]:
    """The recording (15 s nobody, then 10 s the person standing), the hook, the history file; the moment the
    person was last seen in it."""
    header, frames = ru.urfd04(shared_data)
    nobody = ru.held(ru.standing(frames), 0.0, 15.0, nobody=True)      # more than LIVE_FIRST_S (10 s)
    person = ru.held(ru.standing(frames), 15.0, 10.0, seq0=len(nobody))
    recording = ru.write(tmp_path / "absent_then_back.landmarks.jsonl", header, nobody + person)
    script, rec = tmp_path / "hook.sh", tmp_path / "rec"
    script.write_text(HOOK)
    now = time.time()
    quiet = now - 5 * 3600
    fill_history(tmp_path / "state" / "history.sqlite3", quiet - 14.2 * DAY, now - 5, seen_every_s=1800.0,
                 seen_until=quiet)
    hook = f"hooks.on_absent=[{{argv: [/bin/sh, {script}, {rec}], timeout_s: 10}}]"
    return recording, rec, hook, quiet


def _lines(rec: Path) -> list[list[str]]:
    return [line.split("|", 4) for line in rec.read_text().splitlines()] if rec.exists() else []


class Systemd:
    """systemd's side of $NOTIFY_SOCKET: every STATUS= line the daemon sends."""

    def __init__(self, path: Path) -> None:
        self.sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        self.sock.bind(str(path))
        self.sock.settimeout(0.2)
        self.status: list[str] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._read, daemon=True)
        self._thread.start()

    def _read(self) -> None:
        while not self._stop.is_set():
            try:
                message = self.sock.recv(65536).decode()
            except OSError:
                continue
            self.status += [line[7:] for line in message.splitlines() if line.startswith("STATUS=")]

    def close(self) -> None:
        self._stop.set()
        self._thread.join(2.0)
        self.sock.close()


def test_the_person_not_seen_for_longer_than_usual_and_back(tmp_path, shared_data, monkeypatch):
    recording, rec, hook, quiet = _set_up(tmp_path, shared_data)
    systemd = Systemd(tmp_path / "notify.sock")
    monkeypatch.setenv("NOTIFY_SOCKET", str(tmp_path / "notify.sock"))
    try:
        got = replay_to_end(tmp_path, recording, "absentbot", ("status",), *ru.CAMERA, hook,
                            "source.realtime=true", "pipeline.status_period_s=0.5", timeout_s=120.0)
    finally:
        systemd.close()
    lines = _lines(rec)
    assert [x[0] for x in lines] == ["absent", "back"], lines
    absent, back = json.loads(lines[0][4]), json.loads(lines[1][4])
    assert absent["format"] == "posed.absence" and absent["version"] == 1 and absent["robot"] == "absentbot"
    assert absent["absence"] == "absent" and lines[0][2] == "absentbot" and lines[0][3] == "1"
    assert quiet - 1800 <= absent["last_seen_unix"] <= quiet and float(lines[0][1]) == absent["last_seen_unix"]
    history = tmp_path / "state" / "history.sqlite3"
    assert absent["usual_s"] == pytest.approx(expected_usual(history, absent["last_seen_unix"], 14, 7,
                                                             local_zone()), abs=0.1)
    assert 0 < absent["usual_s"] <= USUAL_BOUND_S
    assert absent["notice_after_s"] == pytest.approx(absent["usual_s"] + 3600)
    assert absent["absent_s"] > absent["notice_after_s"] and absent["days"] == 14
    assert back["absence"] == "back" and back["last_seen_unix"] == absent["last_seen_unix"]
    assert back["absent_s"] >= absent["absent_s"] and back["time_unix"] > absent["time_unix"]
    statuses = got["status"]
    for s in statuses:
        contract.validate(s, "status")
    presences = [s["presence"] for s in statuses]
    assert all(p is not None for p in presences)
    gone = [p for p in presences if p["absent"]]
    assert gone, presences
    p = gone[0]
    assert p["usual_s"] == absent["usual_s"] and p["absent_s"] > p["notice_after_s"] and p["days"] == 14
    assert not p["learning"] and p["learn_days"] == 7 and p["absent_since_unix"] == absent["time_unix"]
    assert p["last_seen_unix"] == absent["last_seen_unix"]
    # the person seen: the last statuses say so, with the new sighting
    last = presences[-1]
    assert not last["absent"] and last["absent_since_unix"] is None
    assert last["last_seen_unix"] > absent["time_unix"] - 5 and last["absent_s"] < 60
    out = [json.loads(x) for x in (tmp_path / "out.log").read_text().splitlines() if x.startswith("{")]
    said = [o for o in out if o.get("event") in ("person_absent", "person_back")]
    assert [o["event"] for o in said] == ["person_absent", "person_back"], said
    assert said[0]["level"] == "error" and said[0]["hooks"] == 1
    # systemd's STATUS= line says it while it lasts, and no more once the person is back
    loud = [i for i, line in enumerate(systemd.status) if "; PERSON NOT SEEN FOR 5 h " in line]
    assert loud and all("(usually back within " in systemd.status[i] for i in loud), systemd.status
    running = [line for line in systemd.status if line.startswith("running")]
    assert "PERSON" not in running[-1], systemd.status


@pytest.mark.parametrize("off", ["falls.history_enabled=false", "falls.absence_enabled=false"])
def test_without_the_history_nothing_is_said(tmp_path, shared_data, off):
    recording, rec, hook, _ = _set_up(tmp_path, shared_data)
    got = replay_to_end(tmp_path, recording, "absentbot", ("status",), *ru.CAMERA, hook, off,
                        "pipeline.status_period_s=0.5", timeout_s=120.0)
    assert got["status"] and all("presence" in s and s["presence"] is None for s in got["status"])
    time.sleep(0.5)
    assert not rec.exists()
    out = (tmp_path / "out.log").read_text()
    assert "person_absent" not in out and "absent_hook" not in out
