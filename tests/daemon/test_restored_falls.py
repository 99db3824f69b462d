"""Falls open at a restart, taken back from the real SQLite journal (daemon.stages.restored_falls): which are
open, when their alarm is due (unix time put on this boot's monotonic clock), what the alarm says, a person
found lying after the restart continuing the same event, and recovery only on clear evidence.

The messages before the "restart" are what the publisher journals: the real detector (FallWatch) on a real fall
(urfd_dev's urfd_04) with capture times on the monotonic clock, stamped (payloads.stamp_event) and appended to
an EventJournal in the test's state dir. The fresh detector after it sees real fits of real landmarks."""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np

from posed.daemon.bus.payloads import stamp_event
from posed.daemon.outbox.journal import EventJournal
from posed.daemon.stages.fall_watch import FallWatch
from posed.daemon.stages.restored_falls import RESTORE_HORIZON_S, RestoredFalls
from posed.landmarks.recording import PersonLandmarks
from tests.daemon import restore_util as ru
from tests.daemon.fakes import RecordingLog

ALARM_S = 8.0


def _before_restart(shared_data, journal: EventJournal, cut: str = "on_floor", alarm_s: float = ALARM_S):
    """The run before: urfd_04 through the real detector, its capture clock the monotonic one (the fall just
    happened), messages journalled as the publisher journals them, up to and with the first ``cut`` message
    (the kill came then). Returns the stored messages."""
    cfg = ru.config(f"falls.alarm_after_s={alarm_s}")
    header, frames = ru.urfd04(shared_data)
    base = time.monotonic() - frames[-1].t
    frames = [replace(f, t=base + f.t) for f in frames]
    watch = FallWatch.from_config(cfg.falls, cfg.robot_id, RecordingLog())
    stored = []
    for frame, result, others in ru.fitted(cfg, header, frames):
        for e in watch.update(ru.fit_msg(header, frame, result, others)):
            stored.append(journal.append(stamp_event(e)))
            if e.state == cut:
                return stored
    raise AssertionError(f"no {cut} in urfd_04")


def _journal(tmp_path) -> EventJournal:
    return EventJournal(tmp_path / "state" / "events.sqlite3")


def test_open_falls_are_taken_back_from_the_journal_and_rearmed_in_unix_time(tmp_path, shared_data):
    journal = _journal(tmp_path)
    open_fall = _before_restart(shared_data, journal)
    assert [e.state for e in open_fall] == ["falling", "on_floor"]
    fall = open_fall[0]
    impact_unix = fall.extra["t_impact_unix"]

    def copy(event_id: str, state: str, shift_s: float = 0.0, drop_unix: bool = False):
        e = next(x for x in open_fall if x.state == state) if state in ("falling", "on_floor") else \
            replace(open_fall[-1], state=state)
        extra = {k: (v - shift_s if k.endswith("_unix") and v is not None else v) for k, v in e.extra.items()}
        if drop_unix:       # journalled by a posed that did not stamp unix times
            extra = {k: v for k, v in extra.items() if not k.endswith("_unix")}
        return journal.append(replace(e, id=event_id, wall_time="", extra=extra))

    for state in ("falling", "on_floor", "alarm"):
        copy("alarmed", state)                       # closed: its alarm was raised
    for state in ("on_floor", "recovered"):
        copy("recovered", state)                     # closed: up again
    copy("two-days-old", "on_floor", shift_s=2 * 86400.0)
    journal.acknowledge("two-days-old")             # beyond the horizon and known to a receiver: not re-armed
    legacy = copy("no-unix-times", "on_floor", drop_unix=True)
    journal.acknowledge(fall.id)                    # an acknowledgement closes nothing

    log = RecordingLog()
    now_unix = time.time()
    rebooted = 12.0                                 # the monotonic clock started again since
    restored = RestoredFalls.load(journal, ru.config(f"falls.alarm_after_s={ALARM_S}").falls, log,
                                  now=rebooted, now_unix=now_unix)
    got = {f.id: f for f in restored.open}
    assert set(got) == {fall.id, "no-unix-times"}
    f = got[fall.id]
    assert f.due_unix == impact_unix + ALARM_S
    assert abs(f.due - (impact_unix + ALARM_S - now_unix + rebooted)) < 1e-6
    assert f.sent == {"falling", "on_floor"} and f.t_impact == fall.t_impact and f.t_onset == fall.t_onset
    assert f.features == fall.features and f.carried["t_impact_unix"] == impact_unix
    # without unix times: the journal time of the message less the time from impact to detection
    g = got["no-unix-times"]
    assert abs(g.t_impact_unix - (legacy_wall(journal, legacy) - (legacy.t_detect - legacy.t_impact))) < 1e-6
    # the old one is named, not re-armed
    lines = {e: fields for lv, e, fields in log.lines}
    assert log.events("warning").count("open_fall_restored") == 2
    skipped = lines["open_falls_not_restored"]
    assert skipped["count"] == 1 and skipped["ids"] == ["two-days-old"]
    assert skipped["horizon_h"] == RESTORE_HORIZON_S / 3600.0


def legacy_wall(journal: EventJournal, event) -> float:
    return next(s.wall for s in journal.get(event.id) if s.event.state == event.state)


def test_the_restored_alarm_is_the_detectors_alarm_with_the_same_id_raised_when_due(tmp_path, shared_data):
    journal = _journal(tmp_path)
    before = _before_restart(shared_data, journal)
    first, last = before
    now, now_unix = time.monotonic(), time.time()
    restored = RestoredFalls.load(journal, ru.config(f"falls.alarm_after_s={ALARM_S}").falls, RecordingLog(),
                                  now=now, now_unix=now_unix)
    (f,) = restored.open
    assert f.due > now + 1.0                         # due in the future: the fall happened a moment ago
    assert restored.due(f.due - 0.05) == []
    (alarm,) = restored.due(f.due)
    assert restored.due(f.due + 5.0) == []          # raised once
    assert (alarm.id, alarm.state, alarm.robot) == (first.id, "alarm", first.robot)
    assert (alarm.t_onset, alarm.t_impact, alarm.t_detect) == (first.t_onset, first.t_impact, f.due)
    assert alarm.features == first.features + ("not_recovered",)
    assert alarm.confidence == max(first.confidence, 0.9)
    assert alarm.pose == last.pose and alarm.extra["geometry"] == last.extra["geometry"]
    assert alarm.extra["restored"] == {"at_unix": round(now_unix, 3), "last_state": "on_floor",
                                       "due_unix": round(first.extra["t_impact_unix"] + ALARM_S, 3)}
    # journalled as the publisher does: the unix times of the fall as stored, time_unix the alarm's own
    stamped = journal.append(stamp_event(alarm))
    assert stamped.extra["t_impact_unix"] == first.extra["t_impact_unix"]
    assert stamped.extra["t_onset_unix"] == first.extra["t_onset_unix"]
    assert abs(stamped.extra["time_unix"] - (f.due_unix)) < 0.01
    assert {"format", "version"} <= set(stamped.to_json())
    # the next start finds nothing open
    assert RestoredFalls.load(journal, ru.config().falls, RecordingLog()).open == []


def test_an_alarm_past_due_is_raised_on_the_first_tick(tmp_path, shared_data):
    journal = _journal(tmp_path)
    (first, _) = _before_restart(shared_data, journal)
    later = time.monotonic() + 60.0                  # the daemon came back a minute later
    restored = RestoredFalls.load(journal, ru.config(f"falls.alarm_after_s={ALARM_S}").falls, RecordingLog(),
                                  now=later, now_unix=time.time() + 60.0)
    (alarm,) = restored.due(later)
    assert alarm.id == first.id and alarm.t_detect == later


def _after_restart(shared_data, frames_after, restored: RestoredFalls, cfg, t0: float, others=None):
    """The fresh FallWatch on ``frames_after`` (capture times from ``t0``), the restored falls between frames
    and after each as the publisher calls them; returns every message sent and the watch."""
    header, _ = ru.urfd04(shared_data)
    watch = FallWatch.from_config(cfg.falls, cfg.robot_id, RecordingLog())
    sent = []
    for frame, result, more in ru.fitted(cfg, header, frames_after):
        sent += restored.due(frame.t, watch)
        events = watch.update(ru.fit_msg(header, frame, result, more))
        sent += restored.frame(ru.fit_msg(header, frame, result, more), watch, events, frame.t)
    return sent, watch


def _restart(tmp_path, shared_data, cut="on_floor", alarm_s=ALARM_S):
    journal = _journal(tmp_path)
    before = _before_restart(shared_data, journal, cut, alarm_s)
    cfg = ru.config(f"falls.alarm_after_s={alarm_s}")
    now = time.monotonic()
    restored = RestoredFalls.load(journal, cfg.falls, RecordingLog(), now=now)
    return before, restored, cfg, now


def test_a_person_found_lying_after_the_restart_is_the_same_fall(tmp_path, shared_data):
    before, restored, cfg, now = _restart(tmp_path, shared_data)
    (f,) = restored.open
    header, frames = ru.urfd04(shared_data)
    after = ru.held(ru.lying(frames), now, f.due - now + 1.0)
    sent, watch = _after_restart(shared_data, after, restored, cfg, now)
    # no second event: the fresh detector's found-lying event became the restored one (its on_floor was sent)
    assert {e.id for e in sent} == {before[0].id}
    assert [e.state for e in sent] == ["alarm"]
    alarm = sent[0]
    assert f.due - 1e-6 <= alarm.t_detect <= f.due + 1 / 30 + 1e-6          # on time, on the frames
    assert alarm.t_impact == before[0].t_impact and alarm.t_onset == before[0].t_onset
    assert alarm.features == before[0].features + ("not_recovered",)
    assert alarm.extra["restored"]["last_state"] == "on_floor"
    assert alarm.extra["t_impact_unix"] == before[0].extra["t_impact_unix"]
    assert watch.detector.event_id == before[0].id and watch.detector.state == "alarm"
    assert restored.open[0].handed


def test_found_lying_after_a_restart_that_came_before_on_floor_sends_that_falls_on_floor(tmp_path, shared_data):
    before, restored, cfg, now = _restart(tmp_path, shared_data, cut="falling")
    (f,) = restored.open
    assert f.sent == {"falling"}
    header, frames = ru.urfd04(shared_data)
    sent, _ = _after_restart(shared_data, ru.held(ru.lying(frames), now, f.due - now + 0.5), restored, cfg, now)
    assert [(e.id, e.state) for e in sent] == [(before[0].id, "on_floor"), (before[0].id, "alarm")]
    on_floor = sent[0]
    assert on_floor.features == before[0].features + ("still_on_floor",)
    assert on_floor.t_impact == before[0].t_impact and "restored" in on_floor.extra


def test_seen_up_alone_the_restored_fall_is_recovered_and_no_alarm_follows(tmp_path, shared_data):
    before, restored, cfg, now = _restart(tmp_path, shared_data)
    (f,) = restored.open
    header, frames = ru.urfd04(shared_data)
    assert f.due - now > cfg.falls.recover_s + 1.0
    up = ru.held(ru.standing(frames), now, cfg.falls.recover_s + 0.5)
    nobody = ru.held(ru.standing(frames), up[-1].t + 1 / 30, f.due - up[-1].t + 1.0, seq0=len(up), nobody=True)
    sent, _ = _after_restart(shared_data, up + nobody, restored, cfg, now)
    assert [(e.id, e.state) for e in sent] == [(before[0].id, "recovered")]
    rec = sent[0]
    assert rec.features == ("up_again",) and abs(rec.t_detect - (now + cfg.falls.recover_s)) <= 1 / 30 + 1e-6
    assert rec.t_impact == before[0].t_impact and "restored" in rec.extra
    assert restored.open == []


def test_with_two_people_in_view_nobody_up_recovers_the_restored_fall(tmp_path, shared_data):
    before, restored, cfg, now = _restart(tmp_path, shared_data)
    (f,) = restored.open
    header, frames = ru.urfd04(shared_data)
    lm = ru.standing(frames).landmarks
    other = lm.copy()
    other[:, 0] -= 220.0                          # a second person standing beside, in view
    two = [replace(x, people=(PersonLandmarks(1, lm), PersonLandmarks(2, other)))
           for x in ru.held(ru.standing(frames), now, f.due - now + 0.5)]
    sent, watch = _after_restart(shared_data, two, restored, cfg, now)
    assert len(watch.people.people) == 2
    assert [(e.id, e.state) for e in sent] == [(before[0].id, "alarm")]     # the alarm stands


def test_up_again_then_a_new_fall_seen_after_the_restart(tmp_path, shared_data):
    """urfd_04 again after the restart: the person stands 2 s (alone: the restored fall is recovered), then
    falls (a new event, with its own id)."""
    before, restored, cfg, now = _restart(tmp_path, shared_data)
    header, frames = ru.urfd04(shared_data)
    again = [replace(x, t=now + x.t) for x in frames]
    sent, _ = _after_restart(shared_data, again, restored, cfg, now)
    assert [(e.id, e.state) for e in sent if e.id == before[0].id] == [(before[0].id, "recovered")]
    new = [e for e in sent if e.id != before[0].id]
    assert [e.state for e in new] == ["falling", "on_floor"]
    assert all("restored" not in e.extra for e in new)
    assert restored.open == []


def test_a_fall_seen_while_the_restored_one_is_open_is_a_new_event(tmp_path, shared_data):
    """Nobody seen up for recover_s (the frames start 0.5 s before the descent): the fall seen is a new event,
    never attributed to the restored one, which stays open."""
    before, restored, cfg, now = _restart(tmp_path, shared_data)
    (f,) = restored.open
    header, frames = ru.urfd04(shared_data)
    falling = [replace(x, t=now + x.t - 1.5) for x in frames if x.t >= 1.5]
    sent, _ = _after_restart(shared_data, falling, restored, cfg, now)
    new = [e for e in sent if e.id != before[0].id]
    assert [e.state for e in new][:1] == ["falling"] and all("restored" not in e.extra for e in new)
    assert restored.open and not restored.open[0].handed and restored.seen_up_at is None


def test_the_journal_holds_no_nan(tmp_path, shared_data):
    """The restored alarm round-trips through the journal as JSON (no NaN from a missing value)."""
    journal = _journal(tmp_path)
    _before_restart(shared_data, journal)
    restored = RestoredFalls.load(journal, ru.config().falls, RecordingLog(), now=0.0, now_unix=time.time() + 999)
    (alarm,) = restored.due(0.0)
    journal.append(stamp_event(alarm))
    (back,) = [s.event for s in journal.query() if s.event.state == "alarm"]
    assert back.extra["restored"] == alarm.extra["restored"]
    assert not any(isinstance(v, float) and np.isnan(v) for v in back.extra.values())


def test_two_restored_falls_open_one_person_seen_up_recovers_neither(tmp_path, shared_data):
    """Which of the two got up cannot be told: both alarms stand."""
    journal = _journal(tmp_path)
    before = _before_restart(shared_data, journal)
    for e in before:
        journal.append(replace(e, id="second-fall", wall_time=""))
    cfg = ru.config(f"falls.alarm_after_s={ALARM_S}")
    now = time.monotonic()
    restored = RestoredFalls.load(journal, cfg.falls, RecordingLog(), now=now)
    assert len(restored.open) == 2
    header, frames = ru.urfd04(shared_data)
    due = max(f.due for f in restored.open)
    sent, _ = _after_restart(shared_data, ru.held(ru.standing(frames), now, due - now + 0.5), restored, cfg, now)
    assert sorted((e.id, e.state) for e in sent) == sorted([(before[0].id, "alarm"), ("second-fall", "alarm")])


def test_an_unreadable_journal_is_said_and_does_not_stop_the_stage():
    class Broken:
        path = "events.sqlite3"

        def query(self):
            raise ValueError("a row that is not an event")

    log = RecordingLog()
    assert RestoredFalls.load(Broken(), ru.config().falls, log).open == []
    assert log.events("error") == ["open_falls_unreadable"]
