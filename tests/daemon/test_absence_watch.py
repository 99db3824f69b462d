"""The person not seen for longer than usual (``hooks.on_absent``, daemon/history/absence.py): the live tracker
:class:`PresenceWatch` on a real history file written by :class:`WatchLog` (as the daemon writes it), the notice's
stdin and environment through a real hook program, the config keys and systemd's STATUS= line."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from posed.daemon.config.load import ConfigError
from posed.daemon.config.schema import load_config
from posed.daemon.config.sections import HookConfig, HooksConfig
from posed.daemon.history.absence import REFRESH_S, AbsenceNotice, PresenceWatch
from posed.daemon.history.watched import WatchLog
from posed.daemon.outbox.watch_hooks import WatchHooks
from posed.daemon.supervisor import status_text
from posed.falls.absence import Minutes, usual_absence
from posed.falls.config import FallsConfig

DAY = 86400.0
FRAME_S = 2.0           # history frames 2 s apart: each counts 2 s watched (watched.MAX_FRAME_GAP_S)


class Log:
    """The structlog calls made, as (level, event, fields)."""

    def __init__(self) -> None:
        self.calls: list[tuple[str, str, dict]] = []

    def __getattr__(self, level):
        return lambda event, **fields: self.calls.append((level, event, fields))

    def events(self) -> list[str]:
        return [c[1] for c in self.calls]


def fill_history(path: Path, start: float, end: float, seen_every_s: float | None, seen_until: float | None = None,
                 gaps: tuple[tuple[float, float], ...] = ()) -> None:
    """The history file's ``watched`` minutes as the daemon's WatchLog writes them: frames every 2 s from ``start``
    to ``end`` (unix s; none inside ``gaps``: posed off); a person in view for 10 s every ``seen_every_s`` (from
    ``start``) up to ``seen_until`` (None: to the end), nobody otherwise."""
    seen_until = end if seen_until is None else seen_until
    with WatchLog(path) as w:
        t = start
        while t < end:
            if not any(a <= t < b for a, b in gaps):
                person = seen_every_s is not None and t < seen_until and (t - start) % seen_every_s < 10.0
                w.add(t, person=person, fitted=person)
            t += FRAME_S


def expected_usual(path: Path, t0: float, days: int, learn_days: int, tz=None) -> float | None:
    """The usual for an absence from ``t0`` as falls.absence computes it on the history file, read here on its own
    (WatchLog's readonly mode): what the daemon must have said."""
    with WatchLog(path, readonly=True) as w:
        rows = w.minutes(t0 - days * DAY - 6 * 3600, t0)
    return usual_absence(Minutes.from_rows((r[0], r[4], r[5]) for r in rows), t0, days, learn_days,
                         tz=tz).usual_s


# seen every 30 min, the usual is at most 30 min after the last outing that began within falls.absence's window
# (2 h) after this time of day on past days, counted from this time of day: at most 2.5 h
USUAL_BOUND_S = 2.5 * 3600 + 60


def _watch(path: Path, now: float, log: Log | None = None, **cfg) -> PresenceWatch:
    falls = FallsConfig(**{"absence_days": 3, "absence_learn_days": 2, **cfg})
    return PresenceWatch(path, "r1", falls, log if log is not None else Log(), now_unix=now)


NOW = math.floor(1_780_000_000 / 60) * 60 + 30.0    # a fixed "now" mid-minute


def test_an_absence_longer_than_on_any_day_is_said_once_and_its_end_once(tmp_path):
    """Seen every 30 min for 3.5 days, then watched 5 h with nobody: longer than the usual (+1 h margin), so the
    notice comes at the first tick; 2 s of a person in one minute end it."""
    h = tmp_path / "history.sqlite3"
    quiet = NOW - 5 * 3600
    fill_history(h, NOW - 3.5 * DAY, NOW - 30, seen_every_s=1800.0, seen_until=quiet)
    log = Log()
    w = _watch(h, NOW, log)
    assert w.t0 is not None and quiet - 1800 < w.t0 <= quiet and w.t0 % 60 == 0    # the end of a minute
    assert w.absent_s == pytest.approx(NOW - 30 - w.t0, abs=70)        # every second since was watched
    assert w.state()["absent"] is False and w.state()["usual_s"] is None     # not read before a tick
    assert w.tick(90.0, NOW - 10) is None               # due, but posed has not looked itself yet (LIVE_FIRST_S)
    assert w.state()["usual_s"] is not None and w.state()["notice_after_s"] < w.absent_s
    for i in range(99):                                 # 9.8 s of frames with nobody: still looking
        assert w.add(NOW - 10 + i * 0.1, person=False) is None
    notice = w.add(NOW, person=False)                   # 10 s watched since the start: said
    assert isinstance(notice, AbsenceNotice) and notice.absent
    assert w.tick(100.0, NOW) is None
    st = w.state()
    assert st["absent"] and st["absent_since_unix"] == NOW and st["days"] == 3 and not st["learning"]
    assert st["usual_s"] == pytest.approx(expected_usual(h, w.t0, 3, 2), abs=0.1)
    assert 0 < st["usual_s"] <= USUAL_BOUND_S and st["notice_after_s"] == pytest.approx(st["usual_s"] + 3600)
    assert st["absent_s"] > st["notice_after_s"] and st["last_seen_unix"] == w.t0
    j = notice.to_json()
    assert j["format"] == "posed.absence" and j["absence"] == "absent" and j["robot"] == "r1"
    assert j["last_seen_unix"] == w.t0 and j["usual_s"] == st["usual_s"] and j["days"] == 3
    assert notice.environment() == {"POSED_ABSENT": "absent", "POSED_ABSENT_LAST_SEEN_UNIX": repr(w.t0),
                                    "POSED_ROBOT": "r1"}
    assert w.tick(101.0, NOW + 1) is None                                # once
    # a spurious frame (0.1 s of a person) is not seeing them
    t = math.floor(NOW / 60) * 60 + 61.0
    for i in range(int((t - NOW) * 10)):
        assert w.add(NOW + i * 0.1, person=(i == 50)) is None
    # a person in view: seen again once this minute holds 2 s of them
    back = [n for i in range(40) if (n := w.add(t + i * 0.1, person=True)) is not None]
    assert len(back) == 1 and not back[0].absent and back[0].last_seen_unix == j["last_seen_unix"]
    assert back[0].absent_s > j["absent_s"] and back[0].environment()["POSED_ABSENT"] == "back"
    st = w.state()
    assert st["absent"] is False and st["absent_since_unix"] is None
    # ... and from then on every frame with them in view is the last time seen
    assert st["last_seen_unix"] == pytest.approx(t + 3.9, abs=1e-6) and st["absent_s"] == 0.0 and st["in_view"]
    w.add(t + 4.0, person=False)
    assert not w.state()["in_view"] and w.state()["absent_s"] == pytest.approx(0.1)


def test_a_restart_with_the_person_in_front_of_the_camera_says_nothing(tmp_path):
    """The same history (5 h with nobody, the notice due), but the person stands in front of the camera when the
    daemon starts: seen within its first seconds, before LIVE_FIRST_S, so neither ``absent`` nor ``back``."""
    h = tmp_path / "history.sqlite3"
    fill_history(h, NOW - 3.5 * DAY, NOW - 30, seen_every_s=1800.0, seen_until=NOW - 5 * 3600)
    log = Log()
    w = _watch(h, NOW, log)
    said = [w.tick(90.0, NOW)]
    said += [w.add(NOW + i * 0.1, person=True) for i in range(300)]
    said.append(w.tick(130.0, NOW + 30))
    assert said == [None] * len(said) and log.calls == []
    st = w.state()
    assert not st["absent"] and st["in_view"] and st["absent_s"] == 0.0 and st["days"] == 3


def test_minutes_not_watched_add_nothing(tmp_path):
    """The same days, but posed was off for the last 2 h: 30 min absent at most, no notice."""
    h = tmp_path / "history.sqlite3"
    fill_history(h, NOW - 3.5 * DAY, NOW - 30, seen_every_s=1800.0, gaps=((NOW - 2 * 3600, NOW),))
    w = _watch(h, NOW)
    assert w.absent_s <= 1800 + 60
    assert w.tick(100.0, NOW) is None and w.state()["absent"] is False and w.state()["usual_s"] is not None


def test_while_learning_nothing_is_said(tmp_path):
    """One day of history and learn_days 2: a whole day away (censored) says nothing, the status says learning."""
    h = tmp_path / "history.sqlite3"
    fill_history(h, NOW - 1.2 * DAY, NOW - 30, seen_every_s=1800.0, seen_until=NOW - 0.2 * DAY - 7200)
    w = _watch(h, NOW)
    assert w.absent_s > 7 * 3600
    assert w.tick(100.0, NOW) is None
    st = w.state()
    assert st["learning"] and st["days"] <= 1 and st["usual_s"] is None and st["notice_after_s"] is None
    assert not st["absent"] and st["learn_days"] == 2


def test_live_frames_count_like_the_watch_log(tmp_path):
    """No history at all: never seen; live frames add the time since the one before, at most 2 s; the usual is
    read at the start (the days learned, for the status), then while absent at most once a minute, never per
    frame, and while in view every REFRESH_S."""
    h = tmp_path / "history.sqlite3"
    w = _watch(h, NOW)
    assert w.state()["last_seen_unix"] is None and w.absent_s == 0.0
    reads = []
    real = w._read_usual
    w._read_usual = lambda t0: (reads.append(t0), real(t0))[1]
    w.add(NOW, person=False)
    w.add(NOW + 10.0, person=False)                         # a 10 s gap counts 2 s
    assert w.absent_s == pytest.approx(2.0)
    w.tick(0.0, NOW)
    assert reads == [NOW] and w.state()["days"] == 0        # at the start: never seen, the days from now
    w.tick(1.0, NOW + 1)
    assert len(reads) == 1                                  # not per tick
    t = NOW - NOW % 60 + 60                                  # seen: 2 s of a person in one minute
    for i in range(25):
        w.add(t + i * 0.1, person=True)
    assert w.t0 == pytest.approx(t + 2.4) and w.state()["in_view"]     # the last frame with them in view
    for i in range(100):                                     # out of view, ticking 20 times a second
        w.add(t + 3 + i * 0.05, person=False)
        w.tick(60.0 + i * 0.05, t + 3 + i * 0.05)
    assert len(reads) == 2 and reads[-1] == w.t0             # the usual for this absence, once
    w.tick(140.0, t + 70)
    assert len(reads) == 2                                   # the usual for this t0 was read: not again
    for i in range(25):                                      # seen again: a new absence needs its own
        w.add(t + 120 + i * 0.1, person=True)
    w.add(t + 123, person=False)
    w.tick(100.0, t + 123)
    assert len(reads) == 2                                   # within a minute of the last read
    w.tick(161.5, t + 135)
    assert len(reads) == 3 and w.state()["usual_s"] is None and w.state()["learning"]
    for i in range(25):                                      # in view again, for 10 min: read once more
        w.add(t + 200 + i * 0.1, person=True)
    w.tick(300.0, t + 203)
    assert len(reads) == 3
    w.tick(161.5 + REFRESH_S, t + 203 + REFRESH_S)
    assert len(reads) == 4 and w.state()["in_view"]


def test_a_real_hook_gets_the_absence_and_the_log_names_it(tmp_path):
    rec, script = tmp_path / "rec", tmp_path / "hook.sh"
    script.write_text('rec="$1"\nbody=$(cat)\n'
                      'echo "$POSED_ABSENT|$POSED_ABSENT_LAST_SEEN_UNIX|$POSED_ROBOT|$POSED_HOOK_ATTEMPT|$body" '
                      '>> "$rec"\n'
                      'if [ -e "$rec.fail" ]; then rm "$rec.fail"; exit 3; fi\n')
    Path(f"{rec}.fail").touch()
    hook = HookConfig(argv=("/bin/sh", str(script), str(rec)), timeout_s=10.0, retries=1)
    cfg = HooksConfig(on_absent=(hook,), retry_delay_s=0.1)
    log = Log()
    runner = WatchHooks(cfg, log, cfg.on_absent, key="on_absent", log_as="absent_hook", field="absence")
    absent = AbsenceNotice(True, "r9", 1000.0, 9000.0, 1800.0, 5400.0, 14, 10000.0)
    runner.submit(absent)
    runner.submit(AbsenceNotice(False, "r9", 1000.0, 9100.0, 1800.0, 5400.0, 14, 10100.0))
    runner.close(timeout=10.0)
    lines = [line.split("|", 4) for line in rec.read_text().splitlines()]
    assert [(x[0], x[3]) for x in lines] == [("absent", "1"), ("absent", "2"), ("back", "1")], lines
    assert lines[0][1:3] == ["1000.0", "r9"] and json.loads(lines[0][4]) == absent.to_json()
    assert json.loads(lines[0][4]) == {"format": "posed.absence", "version": 1, "robot": "r9",
                                       "absence": "absent", "last_seen_unix": 1000.0, "absent_s": 9000.0,
                                       "usual_s": 1800.0, "notice_after_s": 5400.0, "days": 14,
                                       "time_unix": 10000.0}
    assert log.events() == ["absent_hook_failed", "absent_hook_done", "absent_hook_done"]
    assert log.calls[0][2]["absence"] == "absent" and log.calls[2][2]["absence"] == "back"


def test_the_config_keys_and_their_cross_check():
    cfg = load_config(None)
    f = cfg.falls
    assert (f.absence_enabled, f.absence_margin_h, f.absence_learn_days, f.absence_days) == (True, 1.0, 7, 14)
    assert cfg.hooks.on_absent == ()
    with pytest.raises(ConfigError) as e:
        load_config(None, overrides=["falls.absence_learn_days=20", "falls.absence_days=10",
                                     "falls.absence_margin_h=0.01"])
    paths = {p.path: p.message for p in e.value.problems}
    assert set(paths) == {"falls.absence_learn_days", "falls.absence_margin_h"}, paths
    assert "more than falls.absence_days (10)" in paths["falls.absence_learn_days"]
    with pytest.raises(ConfigError) as e:
        load_config(None, overrides=["falls.absence_days=91", "hooks.on_absent=[{argv: []}]"])
    assert [p.path for p in e.value.problems] == ["falls.absence_days"]


def test_status_text_says_the_absence():
    status = {"state": "running", "camera": {"state": "open", "source": "v4l2:/dev/video0"}, "fps": 10.0,
              "latency_ms": {"p50": 50, "p95": 80, "max": 90}, "drops": 0, "restarts": 0}
    presence = {"absent": True, "absent_s": 3 * 3600 + 10 * 60 + 59, "usual_s": 2 * 3600 + 5 * 60, "days": 14,
                "learn_days": 7, "learning": False}
    assert status_text(status, None, presence).endswith(
        "; PERSON NOT SEEN FOR 3 h 10 min — longer than on any of the last 14 days (usually back within 2 h 5 min)")
    assert "PERSON" not in status_text(status, None, {**presence, "absent": False})
    assert "PERSON" not in status_text(status)
