"""sd_notify through systemd-python (libsystemd) over a real AF_UNIX datagram socket named by $NOTIFY_SOCKET:
path and abstract addresses, watchdog interval rules."""

import os
import socket
import uuid

from posed.daemon.proc.notify import Notifier


def test_no_socket_means_no_op(monkeypatch):
    monkeypatch.delenv("NOTIFY_SOCKET", raising=False)
    n = Notifier({})
    assert not n.enabled and n.ready() is False and n.watchdog_interval_s is None and n.sent == []


def test_path_socket_receives_messages(tmp_path, monkeypatch):
    path = str(tmp_path / "notify.sock")
    with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM) as sock:
        sock.bind(path)
        monkeypatch.setenv("NOTIFY_SOCKET", path)
        n = Notifier({"WATCHDOG_USEC": "4000000"})
        assert n.watchdog_interval_s == 2.0
        assert n.ready("warm") and n.watchdog() and n.stopping()
        got = [sock.recv(4096).decode() for _ in range(3)]
    assert got == ["READY=1\nSTATUS=warm", "WATCHDOG=1", "STOPPING=1"]
    assert n.sent == got


def test_abstract_socket(monkeypatch):
    name = f"posed-test-{uuid.uuid4().hex}"
    with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM) as sock:
        sock.bind("\0" + name)
        monkeypatch.setenv("NOTIFY_SOCKET", "@" + name)
        n = Notifier()
        assert n.status("hello")
        assert sock.recv(4096) == b"STATUS=hello"


def test_the_messages_go_through_systemd_python(monkeypatch, tmp_path):
    """The design names systemd-python: the Notifier sends with ``systemd.daemon.notify``."""
    from systemd import daemon

    calls = []
    real = daemon.notify

    def spy(status, *a, **kw):
        calls.append(status)
        return real(status, *a, **kw)

    path = str(tmp_path / "n.sock")
    with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM) as sock:
        sock.bind(path)
        monkeypatch.setenv("NOTIFY_SOCKET", path)
        monkeypatch.setattr(daemon, "notify", spy)
        assert Notifier().watchdog()
        assert sock.recv(4096) == b"WATCHDOG=1"
    assert calls == ["WATCHDOG=1"]


def test_watchdog_pid_of_another_process_disables_pings():
    assert Notifier({"WATCHDOG_USEC": "1000000", "WATCHDOG_PID": "1"}).watchdog_interval_s is None
    assert Notifier({"WATCHDOG_USEC": "1000000", "WATCHDOG_PID": str(os.getpid())}).watchdog_interval_s == 0.5


def test_unreachable_socket_reports_without_raising(tmp_path, monkeypatch):
    monkeypatch.setenv("NOTIFY_SOCKET", str(tmp_path / "absent.sock"))
    n = Notifier()
    assert n.ready() is False and "cannot notify" in n.last_error and n.sent == []
