"""The supervisor with real stage processes (the trivial stages of plan_stages.py): restarts after kill -9
and SIGSTOP, escalation, fatal errors, sd_notify order, and a clean, quick SIGTERM shutdown."""

from __future__ import annotations

import json
import os
import signal
import time
from pathlib import Path

import pytest

from tests.daemon.harness import Harness, NotifyListener

STAGES = ("capture", "landmarks", "fitting", "publisher")


@pytest.fixture
def harness(tmp_path):
    made = []

    def make(*overrides, **kw):
        h = Harness(tmp_path, *overrides, **kw)
        made.append(h)
        return h

    yield make
    for h in made:
        if h.proc.poll() is None:
            h.proc.kill()
            h.proc.communicate()


def _ready(s):
    return s["ready"] and s["stages"]["publisher"]["frames"] > 5


def _own_segments(pid: int) -> list[str]:
    return [p.name for p in Path("/dev/shm").glob(f"posed-{pid}-*")]


def _logged(out: str, event: str) -> list[dict]:
    """The supervisor's JSON log lines (its stdout) of one event."""
    rows = []
    for line in out.splitlines():
        try:
            row = json.loads(line)
        except ValueError:
            continue
        if isinstance(row, dict) and row.get("event") == event:
            rows.append(row)
    return rows


def test_kill_each_stage_restarts_it_and_publishing_resumes(harness):
    h = harness("pipeline.max_restarts=10")
    h.wait_for(_ready, 30, "all stages ready")
    for stage in STAGES:
        before = h.latest()
        old_pid = before["stages"][stage]["pid"]
        published = before["stages"]["publisher"]["frames"]
        os.kill(old_pid, signal.SIGKILL)

        def restarted(s, stage=stage, old_pid=old_pid):
            st = s["stages"][stage]
            return st["pid"] != old_pid and st["alive"] and st["state"] == "running"

        # a restart that never comes fails here: spawning a trivial stage takes well under 1 s, the rest of
        # the 10 s is slack for a loaded machine. That it came at once is checked in the log below.
        s = h.wait_for(restarted, 10, f"{stage} restarted")
        assert s["stages"][stage]["restarts"] == 1
        base = published if stage != "publisher" else 0
        h.wait_for(lambda s, base=base: s["stages"]["publisher"]["frames"] > base + 5, 5,
                   f"frames flowing again after killing {stage}")
    assert h.proc.poll() is None
    assert h.latest()["restarts"] == 4
    code, out, err, took = h.stop()
    assert code == 0, err
    assert took < 5.0  # pipeline.shutdown_timeout_s (4 s: then what is still running is killed) + 1 s
    assert _own_segments(h.proc.pid) == []
    # each stage died once and was started again at once: no backoff before a stage's first restart
    # (RestartPolicy), whatever the time the new process then needed to come up
    dead = _logged(out, "stage_dead")
    assert sorted(d["stage"] for d in dead) == sorted(STAGES) and all(d["restart_in_s"] == 0 for d in dead)
    # each restart line is the supervisor's (its own pid, as all its lines) and names the new process apart
    restarted = _logged(out, "stage_restarted")
    assert sorted(r["stage"] for r in restarted) == sorted(STAGES)
    assert all(r["pid"] == h.proc.pid and r["stage_pid"] != h.proc.pid for r in restarted), restarted


def test_sigstop_is_detected_as_stuck_and_restarted(harness):
    h = harness("pipeline.stuck_after_s=1.0")
    h.wait_for(_ready, 30, "all stages ready")
    old = h.latest()["stages"]["fitting"]["pid"]
    os.kill(old, signal.SIGSTOP)
    try:
        # never replaced fails here: 1 s without a heartbeat, a supervisor tick, a spawn; > 8 s of slack
        h.wait_for(lambda s: s["stages"]["fitting"]["pid"] != old and s["stages"]["fitting"]["state"] == "running",
                   10, "the stopped stage replaced")
    finally:
        try:
            os.kill(old, signal.SIGCONT)
        except ProcessLookupError:
            pass
    time.sleep(0.2)
    with pytest.raises(ProcessLookupError):
        os.kill(old, 0)                              # the stuck process was killed, not left behind
    code, out, err, _ = h.stop()
    assert code == 0, err
    # replaced because it was judged stuck by the configured 1 s (the default is 5 s), not for another reason
    stuck = _logged(out, "stage_stuck")
    assert [x["stage"] for x in stuck] == ["fitting"], stuck
    assert "(pipeline.stuck_after_s = 1)" in stuck[0]["reason"] and stuck[0]["restart_in_s"] == 0


def test_notify_sequence_and_watchdog(harness, tmp_path):
    listener = NotifyListener(str(tmp_path / "notify.sock"))
    try:
        h = harness(env={"NOTIFY_SOCKET": listener.sock.getsockname(), "WATCHDOG_USEC": "600000"})
        h.wait_for(_ready, 30, "all stages ready")
        time.sleep(1.5)
        code, _, err, took = h.stop()
        time.sleep(0.2)
    finally:
        listener.close()
    assert code == 0, err
    assert took < 5.0
    messages = [m for _, m in listener.messages]
    kinds = [m.splitlines()[0].split("=")[0] for m in messages]
    first_ready = kinds.index("READY")
    assert "WATCHDOG" not in kinds[:first_ready], "no watchdog ping before READY=1"
    assert kinds.count("READY") == 1
    assert kinds[-1] == "STOPPING"
    assert kinds.count("WATCHDOG") >= 3                         # every 0.3 s for about 1.5 s
    assert any(m.startswith("STATUS=running:") and "fps" in m for m in messages)


def test_escalation_stops_watchdog_pings(harness, tmp_path):
    listener = NotifyListener(str(tmp_path / "notify.sock"))
    try:
        h = harness("pipeline.max_restarts=1",
                    env={"NOTIFY_SOCKET": listener.sock.getsockname(), "WATCHDOG_USEC": "400000"})
        h.wait_for(_ready, 30, "all stages ready")
        for _ in range(2):
            pid = h.latest()["stages"]["publisher"]["pid"]
            os.kill(pid, signal.SIGKILL)
            h.wait_for(lambda s, pid=pid: s["stages"]["publisher"]["pid"] != pid
                       and s["stages"]["publisher"]["alive"], 10, "restart")
        h.wait_for(lambda s: s["state"] == "escalated", 5, "escalation")
        t_esc = time.monotonic()
        time.sleep(1.0)
        assert h.proc.poll() is None
        code, _, _, _ = h.stop()
    finally:
        listener.close()
    assert code == 0
    later = [m for t, m in listener.messages if t > t_esc]
    assert not any(m.startswith("WATCHDOG=1") for m in later), later
    assert any(m.startswith("STATUS=escalated") for _, m in listener.messages)
    pings = [t for t, m in listener.messages if m.startswith("WATCHDOG=1")]
    assert pings, "pings were sent while healthy"


def test_escalation_without_systemd_exits_70(harness):
    h = harness("pipeline.max_restarts=1")
    h.wait_for(_ready, 30, "all stages ready")
    for stage in ("capture", "fitting"):
        pid = h.latest()["stages"][stage]["pid"]
        os.kill(pid, signal.SIGKILL)
        time.sleep(0.3)
    code, out, _, _ = h.stop(sig=0, timeout=15)   # it stops by itself
    assert code == 70
    assert "daemon_escalated" in out and "exiting with 70" in out


def test_fatal_stage_error_exits_78_with_the_fix(harness):
    h = harness(fatal=True)
    code, out, err, _ = h.stop(sig=0, timeout=30)
    assert code == 78
    assert "the test model is missing" in err and "posed models fetch" in err
    assert _own_segments(h.proc.pid) == []


@pytest.mark.parametrize("name", ["walk.landmarks.jsonl", "WALK.LANDMARKS.JSONL"])
def test_a_landmark_recording_in_any_case_skips_the_camera_and_landmark_stages(tmp_path, name):
    from posed.daemon.config import load_config
    from posed.daemon.stages.plan import default_plan

    rec = tmp_path / name
    rec.write_text("")
    plan = default_plan(load_config(None, source=f"file:{rec}"))
    assert [s.name for s in plan] == ["capture", "fitting", "publisher"]
    assert plan[0].entry == "posed.daemon.stages.capture:run_recording"


def test_realsense_recordings_in_any_case_carry_depth():
    from posed.hal import is_realsense_recording

    assert is_realsense_recording("a/b.db3") and is_realsense_recording("B.DB3") and is_realsense_recording("x.Bag")
    assert not is_realsense_recording("squat.mp4") and not is_realsense_recording("db3")
