"""Hook runs survive the publisher's death and the daemon's stop (the audit's defect: a kill -9 of the
publisher 0.2 s after the alarm, or a `systemctl restart`, lost the queued and running hook runs for good).
The real supervisor and publisher on a scripted fall (falls.alarm_after_s 3), a real hook program, the real
journal and real Zenoh on 127.0.0.1:

* kill -9 of the publisher stage while a slow hook (6 s, as a phone call) runs for the alarm: the supervisor
  ends that run and restarts the stage, which runs the hook again for the alarm (POSED_HOOK_ATTEMPT 2,
  POSED_HOOK_REDELIVERED 1) and not for falling and on_floor, which were done; then an acknowledgement with
  ``by`` over Zenoh (raw, and `posed events ack --by`) is kept, logged and answered in the history;
* SIGTERM of the daemon while the falling hook runs and on_floor and alarm wait: logged as pending (not lost);
  the next start runs all three, oldest first, the cut-off one as attempt 2."""

from __future__ import annotations

import json
import os
import signal
import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest
import zenoh

from posed.client import contract
from posed.commands.events import default_by
from tests.daemon.plan_stages import FALL_OVERRIDES
from tests.daemon.redteam_util import FileHarness, until
from tests.daemon.zenoh_util import client, free_port

ROOT = Path(__file__).resolve().parents[2]

# notes each run; sleeps 6 s (a phone call) while REC.slow.STATE or REC.slow.all exists
HOOK = """\
rec="$1"
echo "start $POSED_EVENT_ID $POSED_EVENT_STATE $POSED_HOOK_ATTEMPT $POSED_HOOK_REDELIVERED" >> "$rec"
if [ -e "$rec.slow.$POSED_EVENT_STATE" ] || [ -e "$rec.slow.all" ]; then sleep 6; fi
echo "end $POSED_EVENT_ID $POSED_EVENT_STATE $POSED_HOOK_ATTEMPT" >> "$rec"
"""


def daemon(run_dir: Path, state: Path, rec: Path, *extra: str) -> tuple[FileHarness, str]:
    """The real supervisor and publisher (robot r7) on the scripted fall, with the recording hook."""
    run_dir.mkdir(exist_ok=True)
    script = state.parent / "hook.sh"
    script.write_text(HOOK)
    ep = f"tcp/127.0.0.1:{free_port()}"
    hook = f'hooks.on_event=[{{argv: [/bin/sh, "{script}", "{rec}"], timeout_s: 30, retries: 1}}]'
    h = FileHarness(run_dir, f"zenoh.listen=[{ep}]", f"pipeline.state_dir={state}", "robot_id=r7",
                    "zenoh.event_republish_s=600", *FALL_OVERRIDES, hook, *extra)
    return h, ep


def runs(rec: Path) -> list[tuple[str, ...]]:
    """(start|end, state, attempt[, redelivered]) per line: one fall, one id."""
    out = []
    for line in (rec.read_text().splitlines() if rec.exists() else []):
        kind, _id, *rest = line.split()
        out.append((kind, *rest))
    return out


def journal(state: Path) -> dict[str, tuple]:
    """state -> (hooks_outcome, acked_by, hook attempts) of the fall's messages."""
    with sqlite3.connect(state / "events.sqlite3") as db:
        attempts = dict(db.execute("SELECT state, attempts FROM hook_runs"))
        return {s: (o, b, attempts.get(s)) for s, o, b in
                db.execute("SELECT state, hooks_outcome, acked_by FROM messages")}


def stop(h: FileHarness) -> list[dict]:
    code, _, err, _ = h.stop(timeout=20)
    assert code == 0, err[-2000:]
    return h.log_lines()


@pytest.mark.timeout(90)
def test_kill_9_of_the_publisher_during_the_alarm_hook_runs_it_again_and_only_it(tmp_path):
    state, rec = tmp_path / "state", tmp_path / "rec"
    Path(f"{rec}.slow.alarm").touch()
    h, ep = daemon(tmp_path / "run", state, rec)
    try:
        until(lambda: ("start", "alarm", "1", "0") in runs(rec), 45, "the alarm's hook to start")
        pid = h.latest()["stages"]["publisher"]["pid"]
        os.kill(pid, signal.SIGKILL)                          # mid-call
        Path(f"{rec}.slow.alarm").unlink()                    # the call goes through this time
        until(lambda: ("end", "alarm", "2") in runs(rec), 30, "the alarm's hook to run again after the restart")
        until(lambda: journal(state)["alarm"][0] == "ok", 10, "the alarm marked done")
        assert runs(rec) == [("start", "falling", "1", "0"), ("end", "falling", "1"),
                             ("start", "on_floor", "1", "0"), ("end", "on_floor", "1"),
                             ("start", "alarm", "1", "0"),              # cut off by the kill: no end
                             ("start", "alarm", "2", "1"), ("end", "alarm", "2")]
        assert h.latest()["stages"]["publisher"]["pid"] != pid
        assert {s: v[0] for s, v in journal(state).items()} == {"falling": "ok", "on_floor": "ok", "alarm": "ok"}
        assert journal(state)["alarm"][2] == 2

        # ack `by`: a receiver over Zenoh, then `posed events ack --by` (and its default)
        with sqlite3.connect(state / "events.sqlite3") as db:
            (event_id,) = {r[0] for r in db.execute("SELECT event_id FROM messages")}
        with client(ep) as s:
            s.put("posed/r7/events/ack", json.dumps({"id": event_id, "state": "alarm", "by": "daughter"}))
            until(lambda: journal(state)["alarm"][1] == "daughter", 10, "the alarm acknowledged by daughter")
        env = dict(os.environ)
        common = ["--connect", ep, "--robot", "r7", "--journal", str(state / "events.sqlite3"), "--wait", "10"]
        cli = subprocess.run([sys.executable, "-m", "posed.cli", "events", "ack", event_id[:12], "--state",
                              "on_floor", "--by", "night nurse", *common], cwd=ROOT, env=env, capture_output=True,
                             text=True, timeout=60)
        assert cli.returncode == 0, cli.stdout + cli.stderr
        assert "acknowledged by: night nurse" in cli.stdout
        cli = subprocess.run([sys.executable, "-m", "posed.cli", "events", "ack", event_id, *common], cwd=ROOT,
                             env=env, capture_output=True, text=True, timeout=60)
        assert cli.returncode == 0, cli.stdout + cli.stderr
        assert {s: v[1] for s, v in journal(state).items()} == {
            "falling": default_by(), "on_floor": "night nurse", "alarm": "daughter"}
        with client(ep) as s:
            [reply] = [r.ok for r in s.get("posed/r7/events/history?limit=10")]
            history = json.loads(reply.payload.to_string())
            contract.validate(history)
            assert {e["state"]: (e["acked_by"], e["hooks_outcome"]) for e in history["events"]} == {
                "falling": (default_by(), "ok"), "on_floor": ("night nurse", "ok"), "alarm": ("daughter", "ok")}
            per_message = [json.loads(r.ok.payload.to_string()) for r in
                           s.get("posed/r7/events/history/**", consolidation=zenoh.ConsolidationMode.NONE)]
            assert sorted(o["acked_by"] for o in per_message) == sorted(["daughter", "night nurse", default_by()])
    finally:
        lines = stop(h)
    acked = [x for x in lines if x.get("event") == "fall_event_acknowledged"]
    assert [(x["state"], x["by"]) for x in acked] == [("alarm", "daughter"), ("on_floor", "night nurse"),
                                                     (None, default_by())]
    [again] = [x for x in lines if x.get("event") == "hooks_redelivered"]
    assert [(m["state"], m["attempt"]) for m in again["messages"]] == [("alarm", 2)]
    assert any(x.get("event") == "hooks_left_behind_ended" for x in lines)   # the supervisor ended the first run


@pytest.mark.timeout(90)
def test_sigterm_keeps_queued_hook_runs_pending_for_the_next_start(tmp_path):
    state, rec = tmp_path / "state", tmp_path / "rec"
    Path(f"{rec}.slow.all").touch()
    h, _ = daemon(tmp_path / "run1", state, rec)
    try:
        until(lambda: ("start", "falling", "1", "0") in runs(rec), 45, "the falling hook to start")
        until(lambda: "alarm" in journal(state), 20, "the alarm journalled")
    finally:
        lines = stop(h)                                        # as systemctl stop/restart
    assert runs(rec) == [("start", "falling", "1", "0")]         # on_floor and alarm waited behind it
    [pending] = [x for x in lines if x.get("event") == "hooks_pending_at_shutdown"]
    assert pending["queued"] == 2 and [m.split(":")[1] for m in pending["messages"]] == ["on_floor", "alarm"]
    assert "next start" in pending["note"]
    assert any(x.get("event") == "hook_cut_off_at_shutdown" and x["state"] == "falling" for x in lines)
    assert not [x for x in lines if "abandon" in json.dumps(x) or "lost" in str(x.get("event"))]
    assert journal(state) == {"falling": (None, None, 1), "on_floor": (None, None, None),
                              "alarm": (None, None, None)}

    Path(f"{rec}.slow.all").unlink()
    h, _ = daemon(tmp_path / "run2", state, rec, "falls.enabled=false")      # no new fall: only the journal's
    try:
        until(lambda: len(runs(rec)) == 7, 45, "the three pending runs")
        until(lambda: all(v[0] == "ok" for v in journal(state).values()), 10, "the messages marked done")
    finally:
        lines = stop(h)
    assert runs(rec)[1:] == [("start", "falling", "2", "1"), ("end", "falling", "2"),
                             ("start", "on_floor", "1", "1"), ("end", "on_floor", "1"),
                             ("start", "alarm", "1", "1"), ("end", "alarm", "1")]
    [again] = [x for x in lines if x.get("event") == "hooks_redelivered"]
    assert [m["state"] for m in again["messages"]] == ["falling", "on_floor", "alarm"]
