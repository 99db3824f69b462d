"""Falls restored from the journal under adversity (the red-team of "The alarm across a restart"): the unix clock
stepped between the fall and the restart, and rows of the journal that are not messages.

The run before is the real detector on a real fall (urfd_dev's urfd_04), journalled in a real SQLite journal as
the publisher journals it (tests/daemon/test_restored_falls.py); the clock step is the restart's ``now_unix``
moved against the stored unix times, as a NUC without an RTC battery sees it when NTP steps its clock at boot.
Before the fix: a clock 3 h behind put the alarm 3 h late; a clock 2 days ahead dropped the fall (a warning
only); one row with a damaged body or field stopped the publisher at every start (the daemon escalated, exit 70,
and never watched)."""

from __future__ import annotations

import json
import sqlite3
import time

import structlog

from posed.daemon.outbox.delivery import EventOutbox
from posed.daemon.outbox.hooks import HookRunner
from posed.daemon.outbox.journal import EventJournal
from posed.daemon.stages.restored_falls import RestoredFalls
from tests.daemon import restore_util as ru
from tests.daemon.fakes import RecordingLog
from tests.daemon.test_restored_falls import _before_restart, _journal

ALARM_S = 30.0


def _load(journal, now: float, now_unix: float, log=None) -> RestoredFalls:
    return RestoredFalls.load(journal, ru.config(f"falls.alarm_after_s={ALARM_S}").falls, log or RecordingLog(),
                              now=now, now_unix=now_unix)


def test_a_clock_stepped_back_at_the_restart_raises_the_alarm_at_once_not_hours_late(tmp_path, shared_data):
    journal = _journal(tmp_path)
    first, _ = _before_restart(shared_data, journal, alarm_s=ALARM_S)
    now = time.monotonic()
    log = RecordingLog()
    restored = _load(journal, now, time.time() - 3 * 3600.0, log)      # NTP not yet synced: 3 h behind
    (f,) = restored.open
    assert f.due <= now
    (alarm,) = restored.due(now)
    assert alarm.id == first.id and alarm.state == "alarm"
    assert alarm.extra["restored"]["clock"] == "behind"
    assert alarm.extra["t_impact_unix"] == first.extra["t_impact_unix"]          # as stored
    (fields,) = [x for lv, e, x in log.lines if e == "open_fall_restored"]
    assert fields["clock"] == "behind" and "stepped back" in fields["reason"] and "fix" in fields
    assert log.events("error") == ["open_fall_restored"]


def test_a_small_clock_difference_changes_nothing(tmp_path, shared_data):
    journal = _journal(tmp_path)
    first, _ = _before_restart(shared_data, journal, alarm_s=ALARM_S)
    now, now_unix = time.monotonic(), time.time() - 0.5
    (f,) = _load(journal, now, now_unix).open
    assert f.clock is None and f.due_unix == first.extra["t_impact_unix"] + ALARM_S
    assert f.due > now + 10.0


def test_a_clock_stepped_forward_by_days_raises_the_alarm_at_once_instead_of_dropping_the_fall(tmp_path,
                                                                                               shared_data):
    journal = _journal(tmp_path)
    first, _ = _before_restart(shared_data, journal, alarm_s=ALARM_S)
    now = time.monotonic()
    log = RecordingLog()
    restored = _load(journal, now, time.time() + 2 * 86400.0, log)
    (alarm,) = restored.due(now)
    assert alarm.id == first.id and alarm.extra["restored"]["clock"] == "beyond_horizon"
    assert restored.due(now + 60.0) == []                                # once
    assert "open_falls_not_restored" not in log.events()
    (fields,) = [x for lv, e, x in log.lines if e == "open_fall_restored"]
    assert fields["clock"] == "beyond_horizon" and fields["age_s"] > 86400.0


def test_beyond_the_horizon_an_acknowledged_fall_is_named_not_alarmed(tmp_path, shared_data):
    journal = _journal(tmp_path)
    first, _ = _before_restart(shared_data, journal, alarm_s=ALARM_S)
    journal.acknowledge(first.id, by="carer")
    log = RecordingLog()
    assert _load(journal, time.monotonic(), time.time() + 2 * 86400.0, log).open == []
    assert "open_falls_not_restored" in log.events("warning")


def _damage(journal: EventJournal, good) -> None:
    """A row whose body is not JSON, one whose times are garbage, one whose wall is text: written by hand."""
    db = sqlite3.connect(journal.path)
    body = {**good.to_json(), "id": "bad-fields", "t_impact": "x", "t_impact_unix": None, "geometry": "garbage",
            "features": ["lying_at_floor_level"], "pose": 7}
    rows = [("not-json", "on_floor", "{not json", time.time()),
            ("bad-fields", "on_floor", json.dumps(body), time.time()),
            ("text-wall", "on_floor", json.dumps({**good.to_json(), "id": "text-wall"}), "yesterday")]
    db.executemany("INSERT INTO messages (event_id, state, robot, wall, t_detect, body) VALUES (?, ?, 'r', ?, 1.0, ?)",
                   [(i, s, w, b) for i, s, b, w in rows])
    db.commit()
    db.close()


def test_rows_that_are_not_messages_are_skipped_and_said_once_the_good_fall_is_still_alarmed(tmp_path,
                                                                                           shared_data):
    journal = _journal(tmp_path)
    first, last = _before_restart(shared_data, journal, alarm_s=ALARM_S)
    _damage(journal, last)
    journal.close()
    with structlog.testing.capture_logs() as logged:
        journal = EventJournal(journal.path)
        assert {e.id for e in journal.unacknowledged()} == {first.id, "bad-fields"}
        assert {s.event.id for s, _ in journal.hooks_pending()} == {first.id, "bad-fields"}
        journal.unacknowledged()                                          # said once per row
        now = time.monotonic()
        restored = _load(journal, now, time.time() + ALARM_S + 5.0)
    unreadable = [x for x in logged if x["event"] == "journal_row_unreadable"]
    assert len(unreadable) == 2 and all("rowid" in x and "fix" in x for x in unreadable)
    # the good fall and the one with damaged fields (its journal time stands for its impact) are both alarmed
    alarms = {a.id: a for a in restored.due(now)}
    assert set(alarms) == {first.id, "bad-fields"}
    assert alarms["bad-fields"].t_impact is None and alarms["bad-fields"].extra["geometry"] == "garbage"
    json.dumps(alarms["bad-fields"].to_json())
    journal.close()


def test_the_outbox_starts_on_a_journal_with_a_damaged_row(tmp_path, shared_data):
    journal = _journal(tmp_path)
    _, last = _before_restart(shared_data, journal, alarm_s=ALARM_S)
    _damage(journal, last)
    outbox = EventOutbox(journal, HookRunner(ru.config().hooks), lambda obj: True, RecordingLog(), 600.0)
    try:
        assert outbox.status()["unacknowledged"] == 3                    # falling, on_floor, bad-fields
    finally:
        outbox.close(0.1)
