"""Two posed daemons with one ``robot_id`` on one Zenoh network: found and said loudly.

Every key of a daemon holds its robot id (interfaces.md section 4), so two daemons that share one publish
into each other's topics: a receiver sees two people's poses as one robot's, an acknowledgement and a
history query reach both, and when one of them stops its ``posed/ROBOT/alive`` token goes away for both
(Zenoh keeps one token per key: the receivers hear the robot gone while the other still runs).

So each daemon also holds a liveliness token of its own, ``posed/ROBOT/alive/<instance>`` (the instance: its
Zenoh id, pid and host, so that the log says which machine the other one is on), and follows the tokens under
``posed/ROBOT/alive/*``. Another daemon's token there is a conflict: ``robot_id_in_use`` (an error, again once a
minute while it lasts) and ``zenoh.robot_id_conflict`` in the status; ``robot_id_conflict_ended`` when it is
gone. The receivers' ``posed/*/alive`` does not match these keys.
"""

from __future__ import annotations

import os
import re
import socket
import threading
import time

REMIND_EVERY_S = 60.0
FIX = ("give every posed daemon on one Zenoh network its own robot_id (the config's robot_id, e.g. robot_id: "
       "kitchen); until then their poses, status and fall events are mixed, an acknowledgement or a history query "
       "reaches both, and when one stops the receivers hear the robot gone")


def instance_name(zid: str, pid: int | None = None, host: str | None = None) -> str:
    """One key chunk naming this daemon: ``<zenoh id>.<pid>.<host>`` (the host in key-safe characters)."""
    host = re.sub(r"[^A-Za-z0-9_.-]", "_", host if host is not None else socket.gethostname()) or "host"
    return f"{zid}.{os.getpid() if pid is None else pid}.{host}"


def describe(instance: str) -> str:
    """``pid 12 on host nuc1 (Zenoh id 4f...)`` for an instance name."""
    zid, _, rest = instance.partition(".")
    pid, _, host = rest.partition(".")
    return f"pid {pid} on host {host} (Zenoh id {zid})" if host else instance


class RobotIdWatch:
    """Follows the daemon tokens of one robot id (``on_token``: a liveliness subscriber's callback, on a Zenoh
    thread) and says when another daemon than ``own`` holds one."""

    def __init__(self, robot: str, own: str, log) -> None:
        self.robot, self.own, self.log = robot, own, log
        self._lock = threading.Lock()
        self._others: set[str] = set()
        self._since: float | None = None
        self._next_remind = 0.0

    def on_token(self, sample) -> None:
        import zenoh

        instance = str(sample.key_expr).rsplit("/", 1)[-1]
        if instance == self.own:
            return
        with self._lock:
            before = set(self._others)
            (self._others.add if sample.kind == zenoh.SampleKind.PUT else self._others.discard)(instance)
            others = sorted(self._others)
            if others and not before:
                self._since = time.time()
            elif not others:
                self._since = None
        if others and instance not in before:
            self._say(others)
        elif not others and before:
            self.log.info("robot_id_conflict_ended", robot=self.robot, this_daemon=describe(self.own))

    def remind(self, now: float) -> None:
        """Say it again every REMIND_EVERY_S (``now``: monotonic seconds) while the conflict lasts."""
        with self._lock:
            others = sorted(self._others)
        if not others or now < self._next_remind:
            return
        self._say(others, now)

    def _say(self, others: list[str], now: float | None = None) -> None:
        self._next_remind = (time.monotonic() if now is None else now) + REMIND_EVERY_S
        self.log.error("robot_id_in_use", robot=self.robot, this_daemon=describe(self.own),
                       other_daemons=[describe(o) for o in others],
                       error=f"{len(others)} other posed daemon(s) on this Zenoh network use robot_id "
                             f"{self.robot!r} too", fix=FIX)

    def status(self) -> dict | None:
        """``{"robot", "other_daemons", "since_unix", "error", "fix"}`` while another daemon holds the robot id;
        None otherwise."""
        with self._lock:
            others, since = sorted(self._others), self._since
        if not others:
            return None
        return {"robot": self.robot, "other_daemons": [describe(o) for o in others], "since_unix": since,
                "error": f"{len(others)} other posed daemon(s) on this Zenoh network use robot_id {self.robot!r}",
                "fix": FIX}
