"""The fall alarm is kept across a kill -9 and without frames: the real ``posed run`` (supervisor, capture,
fitting and publisher processes, its own Zenoh port and state dir) on recordings cut from a real fall (urfd_dev's
urfd_04: ``falling`` at 3.3 s, ``on_floor`` at 4.3 s, the recording ending 0.17 s later), the journal read with
``posed events --json`` (docs/falls.md, "The alarm across a restart" and "The alarm without frames").

- kill -9 of the whole daemon after ``on_floor``, restarted on the same state dir with the person still lying in
  view: the alarm comes with the same id at t_impact + alarm_after_s, and no second event;
- kill -9 of the publisher stage alone (the supervisor restarts it at once), nobody in view after: the same;
- the recording ends right after ``on_floor`` (a camera unplugged): the alarm comes when due, once;
- the frames stop for 14 s after ``on_floor`` and come back (a stalled pipeline, a camera that froze): the alarm
  comes when due during the gap; the frames that come back raise nothing again.
"""

from __future__ import annotations

import json
import os
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.daemon import restore_util as ru
from tests.daemon.zenoh_util import free_port

ROOT = Path(__file__).resolve().parents[2]
LATE_S = 0.5          # the alarm within this of its due time: a frame period (0.1 s) and the stage's 50 ms loop


class Daemon:
    """``posed run --source file:RECORDING`` in its own process group, logs as JSON lines in files."""

    def __init__(self, folder: Path, state: Path, source: Path, *overrides: str) -> None:
        folder.mkdir(parents=True, exist_ok=True)
        self.out, self.err = folder / "out.log", folder / "err.log"
        cmd = [sys.executable, "-m", "posed.cli", "run", "--source", f"file:{source}",
               "--set", f"pipeline.state_dir={state}", "--set", "logging.format=json", "--set", "robot_id=kept",
               "--set", f"zenoh.listen=[tcp/127.0.0.1:{free_port()}]", "--set", "zenoh.event_republish_s=600"]
        for o in (*ru.CAMERA, *overrides):
            cmd += ["--set", o]
        with open(self.out, "w") as out, open(self.err, "w") as err:
            self.proc = subprocess.Popen(cmd, cwd=ROOT, stdout=out, stderr=err, start_new_session=True)

    def lines(self) -> list[dict]:
        out = []
        for line in self.out.read_text(errors="replace").splitlines():
            try:
                out.append(json.loads(line))
            except ValueError:
                pass
        return out

    def kill9(self) -> None:
        os.killpg(self.proc.pid, signal.SIGKILL)          # supervisor and stages: the whole group
        self.proc.wait(10)

    def stop(self) -> int:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
        try:
            return self.proc.wait(20)
        except subprocess.TimeoutExpired:
            os.killpg(self.proc.pid, signal.SIGKILL)
            self.proc.wait(10)
            raise

    def alive(self) -> None:
        assert self.proc.poll() is None, f"the daemon exited ({self.proc.returncode}): {self.err.read_text()[-2000:]}"


def journal(state: Path) -> list[dict]:
    """The journal's messages as they are now (read-only, while the daemon writes)."""
    path = state / "events.sqlite3"
    if not path.exists():
        return []
    db = sqlite3.connect(f"file:{path}?mode=ro", uri=True, timeout=5)
    try:
        return [json.loads(b) for (b,) in db.execute("SELECT body FROM messages ORDER BY wall")]
    except sqlite3.OperationalError:
        return []
    finally:
        db.close()


def posed_events(state: Path) -> list[dict]:
    out = subprocess.run([sys.executable, "-m", "posed.cli", "events", "--json", "--set",
                          f"pipeline.state_dir={state}"], cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout)["events"]


def wait_for(pred, timeout: float, what: str, daemon: Daemon):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        v = pred()
        if v:
            return v
        daemon.alive()
        time.sleep(0.02)
    raise AssertionError(f"timed out after {timeout} s waiting for {what}")


def state_of(state: Path, wanted: str):
    return lambda: next((m for m in journal(state) if m["state"] == wanted), None)


def check_alarm(events: list[dict], alarm_s: float) -> dict:
    """One event, each state once, the alarm at t_impact + alarm_after_s (unix time, as journalled)."""
    assert len({e["id"] for e in events}) == 1, [(e["id"][:8], e["state"]) for e in events]
    states = [e["state"] for e in events]
    assert sorted(states) == sorted(set(states)) and states[-1] == "alarm", states
    first, alarm = events[0], events[-1]
    due = first["t_impact_unix"] + alarm_s
    print(f"alarm {alarm['time_unix'] - due:+.3f} s from its due time")
    assert -0.05 <= alarm["time_unix"] - due <= LATE_S, (alarm["time_unix"] - due, alarm)
    assert alarm["t_impact"] == first["t_impact"] and alarm["t_impact_unix"] == first["t_impact_unix"]
    assert alarm["t_onset"] == first["t_onset"]
    assert "not_recovered" in alarm["features"]
    return alarm


@pytest.mark.timeout(120)
def test_kill_9_of_the_daemon_mid_fall_then_found_lying_the_alarm_comes_with_the_same_id(tmp_path, shared_data):
    alarm_s = 15.0
    header, frames = ru.urfd04(shared_data)
    lying = ru.lying(frames)
    fall = ru.write(tmp_path / "fall.landmarks.jsonl", header,
                    frames + ru.held(lying, frames[-1].t + 1 / 30, 10.0, seq0=len(frames)))
    still = ru.write(tmp_path / "lying.landmarks.jsonl", header, ru.held(lying, 0.0, 40.0))
    state = tmp_path / "state"
    first = Daemon(tmp_path / "run1", state, fall, f"falls.alarm_after_s={alarm_s}")
    try:
        on_floor = wait_for(state_of(state, "on_floor"), 60, "on_floor", first)
        first.kill9()                                    # after on_floor, long before the alarm
    finally:
        if first.proc.poll() is None:
            first.kill9()
    assert [m["state"] for m in journal(state)] == ["falling", "on_floor"]
    killed_at = time.time()
    assert on_floor["t_impact_unix"] + alarm_s - killed_at > 8.0

    second = Daemon(tmp_path / "run2", state, still, f"falls.alarm_after_s={alarm_s}")
    try:
        alarm = wait_for(state_of(state, "alarm"), 40, "the alarm", second)
        time.sleep(3.0)                                  # nothing more: no second event, no second alarm
        second.alive()
    finally:
        code = second.stop()
    assert code == 0, second.err.read_text()[-2000:]
    events = posed_events(state)
    alarm = check_alarm(events, alarm_s)
    assert alarm["id"] == on_floor["id"] and alarm["robot"] == "kept"
    assert alarm["restored"]["last_state"] == "on_floor"
    assert alarm["restored"]["due_unix"] == pytest.approx(on_floor["t_impact_unix"] + alarm_s, abs=1e-3)
    assert alarm["restored"]["at_unix"] > killed_at
    assert alarm["features"] == on_floor["features"][:-1] + ["not_recovered"]     # on_floor's: + still_on_floor
    logged = [x["event"] for x in second.lines()]
    assert "open_fall_restored" in logged and "restored_fall_found_lying" in logged
    # the person found lying after the restart was seen by the fresh detector (the same fall, no new id)
    found = next(x for x in second.lines() if x["event"] == "restored_fall_found_lying")
    assert found["id"] == on_floor["id"] and found["new_id"] != on_floor["id"]
    assert found["new_id"] not in {e["id"] for e in events}


@pytest.mark.timeout(120)
def test_kill_9_of_the_publisher_stage_mid_fall_the_alarm_comes_with_the_same_id(tmp_path, shared_data):
    alarm_s = 8.0
    header, frames = ru.urfd04(shared_data)
    rec = ru.write(tmp_path / "fall.landmarks.jsonl", header,
                   frames + ru.held(frames[-1], frames[-1].t + 1 / 30, 25.0, seq0=len(frames), nobody=True))
    state = tmp_path / "state"
    d = Daemon(tmp_path / "run", state, rec, f"falls.alarm_after_s={alarm_s}")
    try:
        on_floor = wait_for(state_of(state, "on_floor"), 60, "on_floor", d)
        pub = next(x["pid"] for x in d.lines() if x.get("component") == "publisher")
        os.kill(pub, signal.SIGKILL)                     # the publisher alone: the supervisor restarts it
        wait_for(lambda: any(x.get("component") == "publisher" and x.get("pid") != pub for x in d.lines()), 20,
                 "the publisher to start again", d)
        wait_for(state_of(state, "alarm"), 30, "the alarm", d)
        time.sleep(2.0)
        d.alive()
    finally:
        code = d.stop()
    assert code == 0, d.err.read_text()[-2000:]
    alarm = check_alarm(posed_events(state), alarm_s)
    assert alarm["id"] == on_floor["id"] and alarm["restored"]["last_state"] == "on_floor"
    assert any(x["event"] == "open_fall_restored" for x in d.lines())


@pytest.mark.timeout(90)
def test_the_recording_ends_after_on_floor_the_alarm_comes_when_due(tmp_path, shared_data):
    """urfd_04 itself: it ends 0.17 s after on_floor (the camera unplugged, a recording ended); the alarm was
    never raised before (no frame, no timer)."""
    alarm_s = 6.0
    state = tmp_path / "state"
    d = Daemon(tmp_path / "run", state, shared_data / ru.URFD04, f"falls.alarm_after_s={alarm_s}")
    try:
        wait_for(state_of(state, "alarm"), 60, "the alarm", d)
        time.sleep(3.0)
        d.alive()
    finally:
        code = d.stop()
    assert code == 0, d.err.read_text()[-2000:]
    alarm = check_alarm(posed_events(state), alarm_s)
    assert alarm["without_frames_s"] >= 3.0                 # raised by the timer, no frame for that long
    assert "restored" not in alarm


@pytest.mark.timeout(90)
def test_frames_stop_after_on_floor_and_come_back_the_alarm_comes_when_due_and_once(tmp_path, shared_data):
    alarm_s = 6.0
    header, frames = ru.urfd04(shared_data)
    back = ru.held(ru.lying(frames), 18.0, 3.0, seq0=1000)        # 13.5 s without frames, then lying again
    rec = ru.write(tmp_path / "gap.landmarks.jsonl", header, frames + back)
    state = tmp_path / "state"
    d = Daemon(tmp_path / "run", state, rec, f"falls.alarm_after_s={alarm_s}")
    try:
        wait_for(state_of(state, "alarm"), 60, "the alarm", d)
        wait_for(lambda: any(x.get("event") == "recording_ended" for x in d.lines()), 30, "the frames' return", d)
        time.sleep(1.0)
        d.alive()
    finally:
        code = d.stop()
    assert code == 0, d.err.read_text()[-2000:]
    events = posed_events(state)
    alarm = check_alarm(events, alarm_s)
    assert [e["state"] for e in events] == ["falling", "on_floor", "alarm"]
    assert alarm["without_frames_s"] >= 3.0 and alarm["t_detect"] < events[0]["t_impact"] + 14.0
