"""A person who may be on the floor is never left unwatched: a real ``posed run`` replaying a real fall (URFD
landmarks) refuses a pause while the fall event is open and not acknowledged, names the event and the fix, and
pauses once it is acknowledged (through the real command line: ``posed pause``, ``posed events ack``)."""

from __future__ import annotations

import sqlite3

from tests.daemon.privacy_util import FALL, PosedRun, posed_cli, wait
from tests.daemon.zenoh_util import free_port


def _journal(state) -> list[tuple]:
    path = state / "events.sqlite3"
    if not path.exists():
        return []
    try:
        with sqlite3.connect(f"file:{path}?mode=ro", uri=True) as db:
            return list(db.execute("SELECT event_id, state, acked_at FROM messages ORDER BY rowid"))
    except sqlite3.OperationalError:        # the daemon is creating it right now (no table yet)
        return []


def test_a_pause_is_refused_while_a_fall_is_open_and_allowed_once_acknowledged(tmp_path, shared_data):
    run = PosedRun(tmp_path, "d", str(shared_data / FALL), "pf1", free_port(), "falls.alarm_after_s=1")
    try:
        # the fall, then its alarm (the recording ends with the person on the floor)
        rows = wait(lambda: [r for r in _journal(run.state) if r[1] == "alarm"], 120, "the fall's alarm", run)
        event_id = rows[0][0]
        refused = posed_cli("pause", "15m", "--by", "voice", "--robot", "pf1", "--connect", run.endpoint)
        assert refused.returncode == 1, (refused.stdout, refused.stderr)
        assert f"fall event {event_id} is open and not acknowledged" in refused.stderr, refused.stderr
        assert f"acknowledge fall {event_id} first" in refused.stderr
        refusals = run.events("privacy_pause_refused")
        assert refusals and event_id in refusals[0]["error"] and refusals[0]["by"] == "voice"
        assert not (run.state / "privacy.json").exists()
        ack = posed_cli("events", "ack", event_id, "--robot", "pf1", "--connect", run.endpoint,
                        "--set", f"pipeline.state_dir={run.state}")
        assert ack.returncode == 0, ack.stderr
        assert all(r[2] is not None for r in _journal(run.state) if r[0] == event_id)
        allowed = posed_cli("pause", "15m", "--by", "voice", "--robot", "pf1", "--connect", run.endpoint)
        assert allowed.returncode == 0, allowed.stderr
        assert "paused until" in allowed.stdout
    finally:
        code = run.stop()
    assert code == 0
