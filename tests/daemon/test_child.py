"""The child daemon of ``posed demo`` and ``posed bench pipeline``: its command line, and stopping it (SIGTERM
first, SIGKILL only when it does not stop in time)."""

from __future__ import annotations

import signal
import subprocess
import sys
import time

from posed.commands import _child, demo

SLEEPER = "import time; print('up', flush=True); time.sleep(60)"
STUBBORN = ("import signal, time; signal.signal(signal.SIGTERM, signal.SIG_IGN); print('up', flush=True); "
            "time.sleep(60)")


def start(code: str) -> subprocess.Popen:
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    assert proc.stdout.readline().strip() == "up"
    return proc


def test_demo_stops_a_daemon_that_never_came_up_with_sigterm(tmp_path, capsys):
    err = tmp_path / "daemon.err"
    err.write_text("zenoh: cannot listen\n")
    proc = start(SLEEPER)
    try:
        t0 = time.monotonic()
        code = demo._failed(proc, "the daemon did not come up", str(err))
        elapsed = time.monotonic() - t0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == -signal.SIGTERM     # asked to stop, not killed after a 10 s wait
    assert elapsed < 5.0
    assert code != 0
    text = capsys.readouterr().err
    assert "the daemon did not come up" in text and "zenoh: cannot listen" in text


def test_stop_kills_a_child_that_ignores_sigterm():
    proc = start(STUBBORN)
    t0 = time.monotonic()
    _child.stop(proc, timeout_s=0.5)
    assert proc.returncode == -signal.SIGKILL
    assert time.monotonic() - t0 < 5.0
    _child.stop(proc, timeout_s=0.5)              # already gone: nothing to do


def test_run_command_puts_the_users_settings_last():
    cmd = _child.run_command(["robot_id=demo", "source.loop=true"], config="my.yaml", source="file:a.mp4",
                             overrides=["robot_id=mine"])
    assert cmd[:4] == [sys.executable, "-m", "posed.cli", "run"]
    sets = [cmd[i + 1] for i, arg in enumerate(cmd) if arg == "--set"]
    assert sets == ["robot_id=demo", "source.loop=true", "robot_id=mine"]
    assert cmd[cmd.index("--config") + 1] == "my.yaml" and cmd[cmd.index("--source") + 1] == "file:a.mp4"
    assert "--config" not in _child.run_command([]) and "--source" not in _child.run_command([])


def test_free_endpoint_is_a_bindable_local_tcp_endpoint():
    import socket

    endpoint = _child.free_endpoint()
    assert endpoint.startswith("tcp/127.0.0.1:")
    with socket.socket() as s:
        s.bind(("127.0.0.1", int(endpoint.rsplit(":", 1)[1])))
