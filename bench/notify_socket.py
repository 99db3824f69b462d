"""A stand-in for systemd's side of the notify protocol: a real AF_UNIX datagram socket (bind it, pass its path
as ``$NOTIFY_SOCKET``) read by a thread, every message kept with its arrival time (``time.monotonic``)."""

from __future__ import annotations

import socket
import threading
import time


class NotifySocket:
    """``messages``: (arrival time, text) per datagram, in order; ``ready_at``: when READY=1 first came."""

    def __init__(self, path: str) -> None:
        self.sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        self.sock.bind(path)
        self.sock.settimeout(0.1)
        self.messages: list[tuple[float, str]] = []
        self._stop = False
        self._thread = threading.Thread(target=self._loop, daemon=True)
        self._thread.start()

    def _loop(self) -> None:
        while not self._stop:
            try:
                self.messages.append((time.monotonic(), self.sock.recv(4096).decode(errors="replace")))
            except TimeoutError:
                continue
            except OSError:   # closed under the thread
                return

    def texts(self, prefix: str = "") -> list[str]:
        """The messages' texts that start with ``prefix``."""
        return [m for _, m in list(self.messages) if m.startswith(prefix)]

    @property
    def ready_at(self) -> float | None:
        return next((t for t, m in list(self.messages) if m.startswith("READY=1")), None)

    def close(self) -> None:
        self._stop = True
        self._thread.join(2)
        self.sock.close()
