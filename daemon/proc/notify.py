"""Messages to the service manager through systemd-python (``systemd.daemon.notify``, libsystemd's sd_notify).

libsystemd sends each message as one AF_UNIX datagram to ``$NOTIFY_SOCKET`` of this process (a path, or
starting with ``@`` a Linux abstract socket name). Without it every call is a no-op returning False, so the
daemon behaves the same outside systemd. The watchdog interval is half of ``WATCHDOG_USEC`` and applies only
when ``WATCHDOG_PID`` is unset or names this process (sd_watchdog_enabled semantics). Protocol: sd_notify(3);
systemd.service(5) for Type=notify and WatchdogSec.
"""

from __future__ import annotations

import os


def _sd_notify():
    """``systemd.daemon.notify``, or None where systemd-python is not installed (it is a Linux-only
    dependency): then nothing is sent."""
    try:
        from systemd import daemon
    except ImportError:
        return None
    return daemon.notify


class Notifier:
    """Messages to the service manager: READY=1, STATUS=..., WATCHDOG=1, STOPPING=1.

    ``environ`` (default ``os.environ``) gives the watchdog settings; the messages go where libsystemd finds
    ``$NOTIFY_SOCKET`` in this process's environment."""

    def __init__(self, environ: dict | None = None) -> None:
        env = os.environ if environ is None else environ
        self.watchdog_interval_s: float | None = None
        usec = env.get("WATCHDOG_USEC", "")
        pid = env.get("WATCHDOG_PID", "")
        if usec.isdigit() and int(usec) > 0 and (not pid or pid == str(os.getpid())):
            self.watchdog_interval_s = int(usec) / 2e6
        self._notify = _sd_notify()
        self.sent: list[str] = []      # what was sent, for logs and tests
        self.last_error = "" if self._notify else "systemd-python is not installed: no sd_notify messages"

    @property
    def address(self) -> str:
        return os.environ.get("NOTIFY_SOCKET", "")

    @property
    def enabled(self) -> bool:
        return bool(self.address) and self._notify is not None

    def send(self, *lines: str) -> bool:
        """Send ``KEY=VALUE`` lines in one datagram; False when not under systemd or on a send error."""
        if not self.enabled:
            return False
        message = "\n".join(lines)
        try:
            delivered = bool(self._notify(message))
        except OSError as exc:
            self.last_error = f"cannot notify the service manager at {self.address!r}: {exc}"
            return False
        if delivered:
            self.sent.append(message)
        return delivered

    def ready(self, status: str = "") -> bool:
        return self.send("READY=1", *((f"STATUS={status}",) if status else ()))

    def status(self, text: str) -> bool:
        return self.send(f"STATUS={text}")

    def watchdog(self) -> bool:
        return self.send("WATCHDOG=1")

    def stopping(self, status: str = "") -> bool:
        return self.send("STOPPING=1", *((f"STATUS={status}",) if status else ()))
