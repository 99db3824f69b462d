"""The chaos campaign's side of the bus (``posed bench chaos``): a router standing in for zenohd, an observer
that receives and acknowledges fall events and times every pose, a subscriber that comes and goes, and an
ack flood. All sessions are zenoh-python on 127.0.0.1, multicast scouting off. Times: ``time.monotonic()``."""

from __future__ import annotations

import json
import queue
import random
import threading
import time


def open_client(endpoint: str, timeout_s: float = 30.0):
    """A client session to ``endpoint``, retried until it answers."""
    import zenoh

    from posed.client import session_config

    deadline = time.monotonic() + timeout_s
    while True:
        try:
            return zenoh.open(session_config("client", connect=[endpoint]))
        except Exception:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.2)


class Observer:
    """Receives pose, status and fall-event messages of one robot; acknowledges a seeded share of the events
    (by id, from its own thread: never from a Zenoh callback)."""

    def __init__(self, session, robot: str, ack_share: float, seed: int) -> None:
        self.session = session
        self.robot = robot
        self.lock = threading.Lock()
        self.pose_times: list[float] = []
        self.statuses: list[tuple[float, dict]] = []
        self.received: dict[tuple[str, str], float] = {}   # (id, state) -> first receipt
        self.receipts = 0                                   # every event message, republications included
        self.acked_ids: set[str] = set()
        self.alarm_bodies: dict[str, set] = {}              # id -> distinct t_detect of its alarm messages
        self._ack_share = ack_share
        self._rng = random.Random(seed)
        self._decided: dict[str, bool] = {}
        self._acks: queue.Queue = queue.Queue()
        self._stop = threading.Event()
        self._keep = [session.declare_subscriber(f"posed/{robot}/pose", self._on_pose),
                      session.declare_subscriber(f"posed/{robot}/status", self._on_status),
                      session.declare_subscriber(f"posed/{robot}/events/fall", self._on_event)]
        self._thread = threading.Thread(target=self._ack_loop, name="chaos-acker", daemon=True)
        self._thread.start()

    def _on_pose(self, sample) -> None:
        with self.lock:
            self.pose_times.append(time.monotonic())

    def _on_status(self, sample) -> None:
        try:
            status = json.loads(sample.payload.to_string())
        except ValueError:
            return
        with self.lock:
            self.statuses.append((time.monotonic(), status))

    def _on_event(self, sample) -> None:
        try:
            event = json.loads(sample.payload.to_string())
            key = (str(event["id"]), str(event["state"]))
        except (ValueError, KeyError, TypeError):
            return
        with self.lock:
            self.receipts += 1
            first = key not in self.received
            self.received.setdefault(key, time.monotonic())
            if key[1] == "alarm":
                self.alarm_bodies.setdefault(key[0], set()).add(event.get("t_detect"))
            if key[0] not in self._decided:
                self._decided[key[0]] = self._rng.random() < self._ack_share
            ack = first and self._decided[key[0]]
        if ack:
            self._acks.put(key[0])

    def _ack_loop(self) -> None:
        while not self._stop.is_set():
            try:
                event_id = self._acks.get(timeout=0.2)
            except queue.Empty:
                continue
            try:
                self.session.put(f"posed/{self.robot}/events/ack", event_id)
                with self.lock:
                    self.acked_ids.add(event_id)
            except Exception:
                pass

    def last_status(self) -> dict | None:
        with self.lock:
            return self.statuses[-1][1] if self.statuses else None

    def poses_since(self, t: float) -> int:
        with self.lock:
            return sum(1 for x in self.pose_times if x >= t)

    def longest_gap(self, t0: float, t1: float) -> tuple[float, float | None]:
        """The longest time without a pose within [t0, t1] (its start, relative to t0)."""
        with self.lock:
            times = [t for t in self.pose_times if t0 <= t <= t1]
        edges = [t0, *times, t1]
        gaps = [(b - a, a - t0) for a, b in zip(edges, edges[1:], strict=False)]
        gap, at = max(gaps) if gaps else (t1 - t0, 0.0)
        return gap, at

    def close(self) -> None:
        self._stop.set()
        self._thread.join(2)
        for entity in self._keep:
            try:
                entity.undeclare()
            except Exception:
                pass


class ComingAndGoing:
    """A subscriber to the fall events that opens its own session, stays a while, closes it, waits, again
    (each arrival makes the daemon publish the unacknowledged events again)."""

    def __init__(self, endpoint: str, robot: str, seed: int, stay_s=(0.5, 3.0), away_s=(0.5, 3.0)) -> None:
        self.endpoint = endpoint
        self.robot = robot
        self.cycles = 0
        self.messages = 0
        self._rng = random.Random(seed)
        self._stay, self._away = stay_s, away_s
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, name="chaos-churn", daemon=True)

    def start(self) -> ComingAndGoing:
        self._thread.start()
        return self

    def _count(self, sample) -> None:
        self.messages += 1

    def _loop(self) -> None:
        while not self._stop.is_set():
            try:
                with open_client(self.endpoint, timeout_s=5.0) as s:
                    s.declare_subscriber(f"posed/{self.robot}/events/fall", self._count)
                    self._stop.wait(self._rng.uniform(*self._stay))
                self.cycles += 1
            except Exception:
                pass
            self._stop.wait(self._rng.uniform(*self._away))

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(10)


def ack_payloads(n: int, seed: int) -> list[bytes]:
    """``n`` hostile acknowledgements: unknown ids, garbage bytes, oversized text, JSON with a bad state."""
    rng = random.Random(seed)
    out = []
    for i in range(n):
        kind = i % 5
        if kind == 0:
            out.append(rng.randbytes(16).hex().encode())
        elif kind == 1:
            out.append(rng.randbytes(rng.randint(1, 64)))
        elif kind == 2:
            out.append(b"x" * 5000)
        elif kind == 3:
            out.append(json.dumps({"id": rng.randbytes(8).hex(), "state": "asleep"}).encode())
        else:
            out.append(json.dumps({"id": rng.randbytes(16).hex()}).encode())
    return out


def ack_flood(session, robot: str, n: int, seed: int) -> dict:
    """Put ``n`` hostile acknowledgements on events/ack as fast as possible."""
    payloads = ack_payloads(n, seed)
    t0 = time.monotonic()
    sent = 0
    for p in payloads:
        try:
            session.put(f"posed/{robot}/events/ack", p)
            sent += 1
        except Exception:
            pass
    return {"sent": sent, "seconds": round(time.monotonic() - t0, 2)}
