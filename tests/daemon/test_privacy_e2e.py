"""Pausing for privacy end to end: a real ``posed run`` replaying the real squat video (looped, at its own pace:
a camera that never stops), real Zenoh on 127.0.0.1 (multicast scouting off), paused through the real command
line (``posed pause``) and through ``PosedClient.pause``/``resume``; a restart during a pause; systemd's STATUS=
line through a real notify socket; the watch hooks run as real programs."""

from __future__ import annotations

import json
import os
import signal
import sqlite3
import subprocess
import sys
import time

from posed.client import PosedClient, PosedClientError
from tests.daemon.harness import NotifyListener
from tests.daemon.privacy_util import ROOT, SQUAT, WATCH_HOOK, PosedRun, Viewer, posed_cli, wait
from tests.daemon.zenoh_util import free_port

GRACE_S = 0.5       # a pose already on the wire when the pause was answered


def _hook_lines(rec) -> list[list[str]]:
    return [line.split("|", 2) for line in rec.read_text().splitlines()] if rec.exists() else []


def test_paused_by_the_command_line_no_pose_said_everywhere_and_resumed_by_itself(tmp_path, shared_data):
    hook, rec = tmp_path / "hook.sh", tmp_path / "rec"
    hook.write_text(WATCH_HOOK)
    listener = NotifyListener(str(tmp_path / "notify.sock"))
    run = PosedRun(tmp_path, "d", f"{shared_data / SQUAT}?loop=true", "pz1", free_port(),
                   f"hooks.on_watch_lost=[{{argv: [/bin/sh, {hook}, {rec}], timeout_s: 10}}]",
                   "hooks.watch_lost_after_s=1.5", notify=str(tmp_path / "notify.sock"))
    viewer = None
    try:
        viewer = Viewer(run.endpoint, "pz1")
        wait(lambda: viewer.poses_between(0) >= 5, 120, "poses before the pause", run)
        pause_s = 12.0
        cli = posed_cli("pause", f"{pause_s:g}s", "--by", "voice", "--robot", "pz1", "--connect", run.endpoint)
        t_paused = time.monotonic()
        assert cli.returncode == 0, cli.stderr
        assert "paused until " in cli.stdout and ", by voice" in cli.stdout, cli.stdout
        t_until = t_paused + pause_s - 0.5
        # the status says it, with privacy, never blind; the watch judgement says why
        st = wait(lambda: next((s for s in viewer.statuses_since(t_paused + GRACE_S) if s["state"] == "paused"),
                               None), 5, "a status saying paused", run)
        assert st["privacy"]["paused"] is True and st["privacy"]["by"] == "voice"
        assert 0 < st["privacy"]["remaining_s"] <= pause_s and st["blind"] is None
        wait(lambda: (viewer.last_status() or {}).get("camera", {}).get("state") == "paused", 5,
             "the capture stage paused", run)
        watch = wait(lambda: (viewer.last_status() or {}).get("watch", {}).get("reason") == "paused"
                     and viewer.last_status()["watch"], 5, "watch: not watching, reason paused", run)
        assert watch["watching"] is False and watch["detail"].startswith("paused for privacy by voice until ")
        # the state query has no pose
        replies = list(viewer.session.get("posed/pz1/state", timeout=5.0))
        state = json.loads(replies[0].ok.payload.to_string())
        assert state["pose"] is None and state["status"]["state"] == "paused"
        # the watch hook said lost, with reason paused
        lost = wait(lambda: [x for x in _hook_lines(rec) if x[0] == "lost"], 8, "the watch hook's lost", run)
        assert lost[0][1].startswith("paused: paused for privacy by voice until "), lost
        assert json.loads(lost[0][2])["reason"] == lost[0][1]
        # ... until it ends by itself, no message needed: poses again, running, the hook's back
        wait(lambda: viewer.poses_between(t_paused + pause_s) >= 3, 30, "poses after the pause ended", run)
        assert viewer.poses_between(t_paused + GRACE_S, t_until) == 0, "a pose was published during the pause"
        during = [s for t, s in list(viewer.statuses) if t_paused + GRACE_S <= t <= t_until]
        assert during and all(s["state"] == "paused" and s["blind"] is None for s in during), \
            sorted({s["state"] for s in during})
        wait(lambda: (viewer.last_status() or {}).get("state") == "running", 10, "running again", run)
        back = wait(lambda: [x for x in _hook_lines(rec) if x[0] == "back"], 10, "the watch hook's back", run)
        assert back[0][1].startswith("paused"), back
        st = viewer.last_status()
        assert st["privacy"]["paused"] is False and st["privacy"]["last"]["ended"] == "time"
        assert st["privacy"]["last"]["by"] == "voice"
        assert [e["ended"] for e in run.events("privacy_pause_ended")] == ["time"]
        assert run.events("capture_paused") and run.events("capture_resumed")
        assert not run.events("blind")
        # systemd's STATUS= said it
        paused_lines = listener.texts("STATUS=PAUSED for privacy until ")
        assert paused_lines and "(by voice)" in paused_lines[0], listener.texts("STATUS=")[-5:]
    finally:
        if viewer is not None:
            viewer.close()
        code = run.stop()
        listener.close()
    assert code == 0


def test_the_client_pauses_a_restart_stays_paused_and_the_client_resumes(tmp_path, shared_data):
    port = free_port()
    source = f"{shared_data / SQUAT}?loop=true"
    run = PosedRun(tmp_path, "first", source, "pz2", port)
    viewer = None
    try:
        viewer = Viewer(run.endpoint, "pz2")
        wait(lambda: viewer.poses_between(0) >= 3, 120, "poses before the pause", run)
        with PosedClient.connect(run.endpoint) as c:
            state = c.pause(3600, "bath", robot="pz2")
            t_paused = time.monotonic()
            assert state.paused and state.by == "bath" and state.robot == "pz2" and not state.clamped
            assert abs(state.until_unix - state.since_unix - 3600) < 1
            longer = c.pause(7200, robot="pz2")                  # above privacy.max_pause_s: cut to it
            assert longer.clamped and longer.since_unix == state.since_unix and longer.by == "bath"
            assert longer.max_pause_s == 3600.0
            wait(lambda: (viewer.last_status() or {}).get("camera", {}).get("state") == "paused", 5,
                 "the capture stage paused", run)
        viewer.close()
        viewer = None
        assert run.stop() == 0
        # started again during the pause: paused from its first status on, no pose, until resumed
        run = PosedRun(tmp_path, "second", source, "pz2", port)
        viewer = Viewer(run.endpoint, "pz2")
        t_start = time.monotonic()
        wait(lambda: run.events("daemon_ready"), 120, "the second daemon ready", run)
        ready = time.monotonic()
        time.sleep(4.0)
        assert viewer.poses_between(t_start) == 0, "the restarted daemon published poses during the pause"
        statuses = viewer.statuses_since(ready + 1.0)
        assert statuses and all(s["state"] == "paused" for s in statuses), sorted({s["state"] for s in statuses})
        assert run.events("privacy_pause_restored")
        assert statuses[-1]["privacy"]["since_unix"] == round(state.since_unix, 3)
        with PosedClient.connect(run.endpoint) as c:
            st = wait(lambda: c.state("pz2").status, 10, "a state reply", run)
            assert st.state == "paused" and st.privacy.paused and st.privacy.by == "bath"
            assert st.not_watching == "paused"
            resumed = c.resume("app", robot="pz2")
            t_resumed = time.monotonic()
            assert not resumed.paused and resumed.until_unix is None
            wait(lambda: viewer.poses_between(t_resumed) >= 3, 30, "poses after resume", run)
            last = wait(lambda: (c.state("pz2").status.privacy.raw.get("last")), 10, "the last pause", run)
            assert last["ended"] == "resumed" and last["resumed_by"] == "app" and last["by"] == "bath"
            assert t_resumed - t_paused > 4
        # the history file has the pause as one row across the restart
        with sqlite3.connect(f"file:{tmp_path / 'state' / 'history.sqlite3'}?mode=ro", uri=True) as db:
            rows = list(db.execute("SELECT by, ended, resumed_by FROM paused"))
        assert rows == [("bath", "resumed", "app")], rows
    finally:
        if viewer is not None:
            viewer.close()
        code = run.stop()
    assert code == 0


def test_pausing_not_allowed_by_config_is_refused_with_the_key_named(tmp_path, shared_data):
    run = PosedRun(tmp_path, "d", f"{shared_data / SQUAT}?loop=true", "pz3", free_port(),
                   "privacy.allow_pause=false")
    try:
        wait(lambda: run.events("zenoh_open"), 120, "the session", run)
        cli = posed_cli("pause", "15m", "--robot", "pz3", "--connect", run.endpoint)
        assert cli.returncode == 1, (cli.stdout, cli.stderr)
        assert "privacy.allow_pause" in cli.stderr
        with PosedClient.connect(run.endpoint) as c:
            try:
                c.pause(60, robot="pz3")
            except PosedClientError as exc:
                assert "privacy.allow_pause is false" in str(exc)
            else:
                raise AssertionError("the pause was not refused")
            assert not c.resume(robot="pz3").paused           # resuming is always allowed
            assert c.resume("app").robot == "pz3"             # no robot named: the one robot up
            for bad in (-1, float("nan"), True):
                try:
                    c.pause(bad, robot="pz3")
                except ValueError as exc:
                    assert "for_s" in str(exc)
                else:
                    raise AssertionError(f"pause({bad!r}) was sent")
            try:
                c.pause(60, "a;b", robot="pz3")
            except ValueError as exc:
                assert "by=" in str(exc)
            else:
                raise AssertionError("a by holding ';' was sent")
        assert run.events("privacy_pause_refused")
        none = posed_cli("pause", "15m", "--robot", "nobody", "--connect", run.endpoint, "--wait", "2")
        assert none.returncode == 69, (none.stdout, none.stderr)
    finally:
        code = run.stop()
    assert code == 0
    gone = posed_cli("resume", "--robot", "pz3", "--connect", run.endpoint, "--wait", "1")
    assert gone.returncode == 69 and "cannot connect" in gone.stderr, gone.stderr


def test_a_live_camera_is_closed_while_paused_and_opened_again_when_the_pause_ends(tmp_path, shared_data):
    """The real daemon on a live camera (tests/daemon/privacy_live_camera.py: the squat video behind the v4l2
    kind, each open and close written down): paused, the camera is closed at once and stays closed (its LED
    would be off), also by a capture stage killed -9 and started again during the pause; the pause ends by itself
    and the camera is opened again, poses coming back."""
    (tmp_path / "cam").mkdir()
    video = tmp_path / "cam" / "camera.mp4"
    os.symlink(shared_data / SQUAT, video)
    camera_log = tmp_path / "cam" / "camera.log"
    port = free_port()
    endpoint = f"tcp/127.0.0.1:{port}"
    cmd = [sys.executable, "-m", "tests.daemon.privacy_live_camera"]
    for o in ("source.type=v4l2", f"source.device={video}", "robot_id=pcam", f"pipeline.state_dir={tmp_path / 's'}",
              f"zenoh.listen=[{endpoint}]", "pipeline.status_period_s=0.5"):
        cmd += ["--set", o]
    proc = subprocess.Popen(cmd, cwd=ROOT, stdout=open(tmp_path / "out.log", "w"),
                            stderr=open(tmp_path / "err.log", "w"), start_new_session=True)

    def said() -> list[str]:
        return [line.split()[0] for line in camera_log.read_text().splitlines()] if camera_log.exists() else []

    viewer = None
    try:
        viewer = Viewer(endpoint, "pcam")
        deadline = time.monotonic() + 120
        while viewer.poses_between(0) < 3:
            assert time.monotonic() < deadline and proc.poll() is None, (tmp_path / "err.log").read_text()[-2000:]
            time.sleep(0.1)
        assert said() == ["open"]
        assert viewer.last_status()["camera"]["kind"] == "v4l2"
        with PosedClient.connect(endpoint) as c:
            state = c.pause(14, "visitor", robot="pcam")
        t_paused = time.monotonic()
        assert state.paused
        deadline = time.monotonic() + 5
        while said() != ["open", "close"]:
            assert time.monotonic() < deadline, said()
            time.sleep(0.05)
        closed_after_s = time.monotonic() - t_paused
        assert closed_after_s < 2.0
        pid = viewer.last_status()["stages"]["capture"]["pid"]
        os.kill(pid, signal.SIGKILL)
        deadline = time.monotonic() + 20
        while (viewer.last_status()["stages"]["capture"]["pid"] == pid
               or viewer.last_status()["stages"]["capture"]["state"] != "running"):
            assert time.monotonic() < deadline, viewer.last_status()["stages"]["capture"]
            time.sleep(0.1)
        time.sleep(3.0)
        assert said() == ["open", "close"], "the camera was opened during the pause"
        st = viewer.last_status()
        assert st["state"] == "paused" and st["camera"]["state"] == "paused" and st["blind"] is None
        assert viewer.poses_between(t_paused + GRACE_S) == 0
        deadline = time.monotonic() + 30
        while viewer.poses_between(t_paused + 14.0) < 3:
            assert time.monotonic() < deadline, (said(), viewer.last_status()["state"])
            time.sleep(0.1)
        assert said() == ["open", "close", "open"]
        wait(lambda: (viewer.last_status() or {}).get("camera", {}).get("state") == "open", 5, "the camera open")
    finally:
        if viewer is not None:
            viewer.close()
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
        code = proc.wait(20)
    assert code == 0, (tmp_path / "err.log").read_text()[-2000:]
