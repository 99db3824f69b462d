"""The publisher's keeper of a pause for privacy (``daemon.stages.privacy_keeper.PrivacyKeeper``) on a real state
directory, a real mailbox (the capture stage's ``PauseGate`` reading it) and a real history file (``PauseLog``),
with a clock the test moves: start, clamp, extend and shorten, resume, expiry, refusals, privacy.json kept across
a restart (and ignored when expired or unreadable)."""

from __future__ import annotations

import json
import os
import stat

import pytest
import structlog

from posed.daemon.bus.pause_query import PauseRefused, PauseRequest
from posed.daemon.config.sections import PrivacyConfig
from posed.daemon.history.paused import PauseLog
from posed.daemon.logs import get
from posed.daemon.proc.mailbox import Mailbox
from posed.daemon.stages.privacy_file import PRIVACY_FILE, read_privacy_file
from posed.daemon.stages.privacy_gate import PauseGate
from posed.daemon.stages.privacy_keeper import PrivacyKeeper

T0 = 1_800_000_000.0
DEFAULT = PrivacyConfig()


class Clock:
    def __init__(self) -> None:
        self.t = T0

    def __call__(self) -> float:
        return self.t


@pytest.fixture
def box():
    return Mailbox("privacy", bytearray(Mailbox.size(4096)), 0, 4096)


def keeper(tmp_path, clock, box=None, cfg=DEFAULT, open_fall=lambda: None, log_file=True):
    pause_log = PauseLog(tmp_path / "history.sqlite3", get("test"), clock=clock) if log_file else None
    return PrivacyKeeper(cfg, "r1", tmp_path, get("test"), mailbox=box, pause_log=pause_log, open_fall=open_fall,
                         wall=clock)


def rows(tmp_path):
    log = PauseLog(tmp_path / "history.sqlite3", readonly=True)
    try:
        return log.between(0.0, 4e9)
    finally:
        log.close()


def test_a_pause_is_kept_forwarded_said_and_ends_by_itself(tmp_path, box):
    clock = Clock()
    k = keeper(tmp_path, clock, box)
    gate = PauseGate(box, None, get("test"), wall=clock)
    assert not gate.paused()                                   # the first order: watching
    with structlog.testing.capture_logs() as logged:
        reply = k.ask(PauseRequest(900.0, "voice"))
    assert reply == {"format": "posed.privacy", "version": 1, "robot": "r1", "time_unix": T0, "paused": True,
                     "since_unix": T0, "until_unix": T0 + 900, "by": "voice", "remaining_s": 900.0, "clamped": False,
                     "max_pause_s": 3600.0}
    assert [e["event"] for e in logged] == ["privacy_pause_started"]
    assert gate.paused() and gate.pause.until_unix == T0 + 900          # handed to the capture stage
    path = tmp_path / PRIVACY_FILE
    assert stat.S_IMODE(os.stat(path).st_mode) == 0o600
    pause, last = read_privacy_file(path)
    assert (pause.since_unix, pause.until_unix, pause.by, last) == (T0, T0 + 900, "voice", None)
    clock.t += 300
    st = k.status()
    assert st == {"allow_pause": True, "max_pause_s": 3600.0, "paused": True, "since_unix": T0,
                  "until_unix": T0 + 900, "remaining_s": 600.0, "by": "voice"}
    clock.t = T0 + 900
    assert not gate.paused()                                   # the capture stage's own clock ends it too
    with structlog.testing.capture_logs() as logged:
        k.tick(0.0)
    assert [e["event"] for e in logged] == ["privacy_pause_ended"] and logged[0]["ended"] == "time"
    st = k.status()
    assert st["paused"] is False and "until_unix" not in st
    assert st["last"] == {"since_unix": T0, "ended_unix": T0 + 900, "by": "voice", "ended": "time",
                          "resumed_by": None}
    assert read_privacy_file(path)[0] is None
    k.close()
    assert [(r.since_unix, r.until_unix, r.ended_unix, r.by, r.ended) for r in rows(tmp_path)] == \
        [(T0, T0 + 900, T0 + 900, "voice", "time")]


def test_a_wall_clock_stepped_back_does_not_stretch_a_pause(tmp_path, box):
    """NTP steps a clock that ran a day ahead back during a pause: the pause still ends after the seconds it
    was given (the monotonic clock), not a day later."""
    wall, mono = Clock(), Clock()
    mono.t = 500.0
    k = PrivacyKeeper(DEFAULT, "r1", tmp_path, get("test"), mailbox=box, wall=wall, mono=mono)
    gate = PauseGate(box, None, get("test"), wall=wall)
    k.ask(PauseRequest(900.0, "voice"))
    wall.t -= 86400.0                       # the wall clock stepped back a day
    k.tick(mono.t + 899.0)
    assert k.paused and gate.paused()
    k.tick(mono.t + 900.0)                  # 900 s have passed, whatever the wall clock says
    assert not k.paused and not gate.paused()
    assert k.status()["last"]["ended"] == "time"


def test_clamped_to_max_pause_s(tmp_path):
    clock = Clock()
    k = keeper(tmp_path, clock, cfg=PrivacyConfig(max_pause_s=600.0))
    reply = k.ask(PauseRequest(7200.0, None))
    assert reply["clamped"] is True and reply["until_unix"] == T0 + 600 and reply["by"] is None
    assert k.message()["clamped"] is True
    k.close()


def test_a_new_pause_replaces_the_running_one_and_keeps_its_start(tmp_path, box):
    clock = Clock()
    k = keeper(tmp_path, clock, box)
    gate = PauseGate(box, None, get("test"), wall=clock)
    k.ask(PauseRequest(900.0, "voice"))
    clock.t += 100
    longer = k.ask(PauseRequest(1800.0, "app"))
    assert (longer["since_unix"], longer["until_unix"], longer["by"]) == (T0, T0 + 1900, "app")
    assert gate.paused() and gate.pause.until_unix == T0 + 1900
    clock.t += 100
    shorter = k.ask(PauseRequest(60.0, None))                  # nobody named: the running pause's asker stays
    assert (shorter["since_unix"], shorter["until_unix"], shorter["by"]) == (T0, T0 + 260, "app")
    k.close()
    assert [(r.since_unix, r.until_unix, r.by) for r in rows(tmp_path)] == [(T0, T0 + 260, "app")]


def test_resume_now_and_resume_when_not_paused(tmp_path, box):
    clock = Clock()
    k = keeper(tmp_path, clock, box)
    gate = PauseGate(box, None, get("test"), wall=clock)
    assert k.ask(PauseRequest(0.0, "app"))["paused"] is False   # nothing to resume: still an answer
    k.ask(PauseRequest(900.0, "voice"))
    assert gate.paused()
    clock.t += 42
    reply = k.ask(PauseRequest(0.0, "app"))
    assert reply["paused"] is False and reply["since_unix"] is None and reply["until_unix"] is None
    assert not gate.paused()
    assert k.status()["last"] == {"since_unix": T0, "ended_unix": T0 + 42, "by": "voice", "ended": "resumed",
                                  "resumed_by": "app"}
    k.close()
    assert [(r.ended_unix, r.ended, r.resumed_by) for r in rows(tmp_path)] == [(T0 + 42, "resumed", "app")]


def test_refused_while_a_fall_is_open_or_by_config_resume_always_allowed(tmp_path):
    clock = Clock()
    fall = ["0a1b2c3d4e5f"]
    k = keeper(tmp_path, clock, open_fall=lambda: fall[0])
    with structlog.testing.capture_logs() as logged, pytest.raises(PauseRefused) as exc:
        k.ask(PauseRequest(900.0, "voice"))
    assert "fall event 0a1b2c3d4e5f is open and not acknowledged" in exc.value.error
    assert "acknowledge fall 0a1b2c3d4e5f first" in exc.value.fix
    assert [e["event"] for e in logged] == ["privacy_pause_refused"]
    assert not k.paused and not (tmp_path / PRIVACY_FILE).exists()
    fall[0] = None
    assert k.ask(PauseRequest(900.0, "voice"))["paused"] is True
    k.close()

    off = keeper(tmp_path / "off", clock, cfg=PrivacyConfig(allow_pause=False), log_file=False)
    with pytest.raises(PauseRefused, match="privacy.allow_pause is false"):
        off.ask(PauseRequest(60.0, None))
    assert off.ask(PauseRequest(0.0, None))["paused"] is False
    assert off.status()["allow_pause"] is False


def test_a_restart_during_a_pause_stays_paused_until_it_ends(tmp_path, box):
    clock = Clock()
    k = keeper(tmp_path, clock)
    k.ask(PauseRequest(900.0, "voice"))
    clock.t += 60
    k.close()                                                   # the daemon stops: the row closed as stopped
    assert [r.ended for r in rows(tmp_path)] == ["stopped"]
    clock.t += 30
    with structlog.testing.capture_logs() as logged:
        again = keeper(tmp_path, clock, box)
    assert [e["event"] for e in logged] == ["privacy_pause_restored"]
    assert again.paused and again.status()["until_unix"] == T0 + 900 and again.status()["since_unix"] == T0
    assert PauseGate(box, None, get("test"), wall=clock).paused()           # forwarded at once
    assert PauseGate(None, tmp_path, get("test"), wall=clock).paused()      # a capture stage starting reads the file
    assert [(r.since_unix, r.ended) for r in rows(tmp_path)] == [(T0, None)]   # one pause, one row, open again
    clock.t = T0 + 901
    again.tick(0.0)
    assert not again.paused
    again.close()
    assert [(r.since_unix, r.ended_unix, r.ended) for r in rows(tmp_path)] == [(T0, T0 + 900, "time")]


def test_an_expired_file_is_ignored_and_said(tmp_path):
    clock = Clock()
    k = keeper(tmp_path, clock, log_file=False)
    k.ask(PauseRequest(600.0, "voice"))
    clock.t += 3600                                             # the daemon was off past the end
    with structlog.testing.capture_logs() as logged:
        again = keeper(tmp_path, clock, log_file=False)
    assert not again.paused
    assert logged[0]["event"] == "privacy_file_ignored" and "ended" in logged[0]["reason"]
    assert again.status()["last"]["ended"] == "time"
    assert not PauseGate(None, tmp_path, get("test"), wall=clock).paused()


@pytest.mark.parametrize("content", [b"{not json", b'{"format": "other"}', b"\xff\xfe",
                                     b'{"format": "posed.privacy_file", "pause": {"since_unix": "x"}}'])
def test_an_unreadable_file_is_ignored_and_said(tmp_path, content):
    (tmp_path / PRIVACY_FILE).write_bytes(content)
    clock = Clock()
    with structlog.testing.capture_logs() as logged:
        k = keeper(tmp_path, clock, log_file=False)
    assert not k.paused
    assert [e["event"] for e in logged] == ["privacy_file_ignored"] and logged[0]["error"]
    assert not PauseGate(None, tmp_path, get("test"), wall=clock).paused()
    k.ask(PauseRequest(60.0, None))                             # and written afresh at the next pause
    assert json.loads((tmp_path / PRIVACY_FILE).read_text())["pause"]["until_unix"] == T0 + 60


def test_a_restored_pause_is_cut_to_a_lowered_max_and_dropped_when_pausing_is_no_longer_allowed(tmp_path):
    clock = Clock()
    k = keeper(tmp_path, clock, log_file=False, cfg=PrivacyConfig(max_pause_s=3600.0))
    k.ask(PauseRequest(3600.0, None))
    again = keeper(tmp_path, clock, log_file=False, cfg=PrivacyConfig(max_pause_s=600.0))
    assert again.status()["until_unix"] == T0 + 600
    with structlog.testing.capture_logs() as logged:
        off = keeper(tmp_path, clock, log_file=False, cfg=PrivacyConfig(allow_pause=False))
    assert not off.paused and logged[0]["event"] == "privacy_file_ignored"


def test_a_state_dir_that_cannot_be_written_is_said_and_the_pause_holds(tmp_path):
    clock = Clock()
    blocker = tmp_path / "file"
    blocker.write_text("")
    with structlog.testing.capture_logs() as logged:
        k = PrivacyKeeper(PrivacyConfig(), "r1", blocker / "state", get("test"), wall=clock)
        reply = k.ask(PauseRequest(60.0, None))
    assert reply["paused"] is True and k.paused
    assert [e["event"] for e in logged] == ["privacy_file_ignored",          # cannot even be read
                                            "privacy_file_not_saved", "privacy_pause_started"]
    assert "save_error" in k.status()
