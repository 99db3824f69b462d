"""The minutes posed watched (daemon.history.watched), as the publisher's recorder writes them beside the angle
history: every frame counts (a person in view or not), the seconds between frames are summed per minute (a gap
longer than MAX_FRAME_GAP_S is not watching), readers of an older history are told it is not recorded, and a
write that fails is logged, never raised."""

from __future__ import annotations

import sqlite3

from posed.daemon import clock
from posed.daemon.history.recorder import HistoryRecorder
from posed.daemon.history.store import AngleHistory
from posed.daemon.history.watched import MAX_FRAME_GAP_S, WatchLog
from posed.falls.config import FallsConfig
from posed.fitting import FitResult


class Log:
    def __init__(self) -> None:
        self.errors: list[tuple[str, dict]] = []

    def error(self, event, **kw) -> None:
        self.errors.append((event, kw))


def test_the_recorder_counts_every_frame_in_its_minute(tmp_path):
    path = tmp_path / "history.sqlite3"
    log = Log()
    rec = HistoryRecorder(AngleHistory(path, FallsConfig()), log)
    t0 = clock.now()
    wall0 = clock.wall_from_monotonic(t0)
    n = 0
    for i in range(300):                    # 30 s of nobody, then 30 s of a person, at 10 fps
        t = t0 + i / 10.0
        person = i >= 150
        r = FitResult(i, t, True, joint_angles_deg={"theta_kn_l": 10.0}) if person else \
            FitResult.failure(i, t, "no person")
        rec.add(r, t)
        n += 1
    rec.close()
    with WatchLog(path, readonly=True) as w:
        rows = w.minutes(wall0 - 120, wall0 + 120)
    assert sum(r[1] for r in rows) == n and sum(r[2] for r in rows) == 150 and sum(r[3] for r in rows) == 150
    assert abs(sum(r[4] for r in rows) - 29.9) < 1e-6 and abs(sum(r[5] for r in rows) - 15.0) < 1e-6
    assert all(r[0] % 60 == 0 for r in rows) and not log.errors


def test_gaps_are_not_watching_and_flushes_add_up(tmp_path):
    with WatchLog(tmp_path / "h.sqlite3") as w:
        for t in (6000.0, 6001.0, 6100.0, 6101.0):   # a 99 s gap (no frames): counts MAX_FRAME_GAP_S at most
            w.add(t, person=True, fitted=False)
            w.flush()                                 # each flush adds to the minute's row
        rows = w.minutes(6000.0, 6200.0)
    assert [(r[0], r[1], r[2]) for r in rows] == [(6000, 2, 2), (6060, 2, 2)]
    assert [r[4] for r in rows] == [1.0, MAX_FRAME_GAP_S + 1.0]


def test_an_older_history_says_it_does_not_know(tmp_path):
    path = tmp_path / "old.sqlite3"
    sqlite3.connect(path).execute("CREATE TABLE angles (wall REAL)").connection.close()
    with WatchLog(path, readonly=True) as w:
        assert w.minutes(0, 1e10) is None


def test_a_failed_write_is_logged_not_raised(tmp_path):
    path = tmp_path / "h.sqlite3"
    log = Log()
    w = WatchLog(path, log)
    w._db.execute("DROP TABLE watched")               # the file lost its table under the daemon
    w.add(1000.0, True, True)
    w.flush()
    assert log.errors and log.errors[0][0] == "watched_write_failed" and "fix" in log.errors[0][1]
    w.close()


def test_the_watched_minutes_are_written_as_often_as_the_angles(tmp_path):
    """A report made seconds after the start reads the minutes posed watched, not only its angle rows (they
    were written once a minute, the angles every falls.history_commit_every_s)."""
    path = tmp_path / "history.sqlite3"
    cfg = FallsConfig()
    rec = HistoryRecorder(AngleHistory(path, cfg), Log(), now=0.0)
    t0 = clock.now()
    wall0 = clock.wall_from_monotonic(t0)
    for i in range(80):                     # 8 s at 10 fps, the recorder ticked as the publisher ticks it
        t = t0 + i / 10.0
        rec.add(FitResult(i, t, True, joint_angles_deg={"theta_kn_l": 10.0}), t)
        rec.tick(i / 10.0)
    with WatchLog(path, readonly=True) as w:
        rows = w.minutes(wall0 - 120, wall0 + 120)
    assert sum(r[1] for r in rows) >= 50, rows        # written at 5 s, not held until the minute's flush
    rec.close()
