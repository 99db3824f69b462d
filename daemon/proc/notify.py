"""sd_notify without a compiled dependency: one AF_UNIX datagram per message to ``$NOTIFY_SOCKET``.

``NOTIFY_SOCKET`` may be a path or, starting with ``@``, a Linux abstract socket name. Without it every call
is a no-op returning False, so the daemon behaves the same outside systemd. The watchdog interval is half of
``WATCHDOG_USEC`` and applies only when ``WATCHDOG_PID`` is unset or names this process (sd_watchdog_enabled
semantics). Protocol: sd_notify(3); systemd.service(5) for Type=notify and WatchdogSec.
"""

from __future__ import annotations

import os
import socket


class Notifier:
    """Messages to the service manager: READY=1, STATUS=..., WATCHDOG=1, STOPPING=1."""

    def __init__(self, environ: dict | None = None) -> None:
        env = os.environ if environ is None else environ
        addr = env.get("NOTIFY_SOCKET", "")
        self.address = ("\0" + addr[1:]) if addr.startswith("@") else addr
        self.watchdog_interval_s: float | None = None
        usec = env.get("WATCHDOG_USEC", "")
        pid = env.get("WATCHDOG_PID", "")
        if usec.isdigit() and int(usec) > 0 and (not pid or pid == str(os.getpid())):
            self.watchdog_interval_s = int(usec) / 2e6
        self.sent: list[str] = []      # what was sent, for logs and tests
        self.last_error = ""

    @property
    def enabled(self) -> bool:
        return bool(self.address)

    def send(self, *lines: str) -> bool:
        """Send ``KEY=VALUE`` lines in one datagram; False when not under systemd or on a send error."""
        if not self.address:
            return False
        message = "\n".join(lines)
        try:
            with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM | socket.SOCK_CLOEXEC) as sock:
                sock.setblocking(False)     # a receiver that does not read must never stall the daemon
                sock.connect(self.address)
                sock.send(message.encode())
        except OSError as exc:
            self.last_error = f"cannot notify the service manager at {self.address!r}: {exc}"
            return False
        self.sent.append(message)
        return True

    def ready(self, status: str = "") -> bool:
        return self.send("READY=1", *((f"STATUS={status}",) if status else ()))

    def status(self, text: str) -> bool:
        return self.send(f"STATUS={text}")

    def watchdog(self) -> bool:
        return self.send("WATCHDOG=1")

    def stopping(self, status: str = "") -> bool:
        return self.send("STOPPING=1", *((f"STATUS={status}",) if status else ()))
