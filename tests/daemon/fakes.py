"""Stand-ins for the unit tests of the publisher's parts: a logger that records, and a Zenoh session that
records what is declared on it (no network)."""

from __future__ import annotations

from types import SimpleNamespace


class RecordingLog:
    """Records ``log.<level>(event, **fields)`` calls as (level, event, fields)."""

    def __init__(self) -> None:
        self.lines: list[tuple[str, str, dict]] = []

    def __getattr__(self, level: str):
        return lambda event, **fields: self.lines.append((level, event, fields))

    def events(self, level: str | None = None) -> list[str]:
        return [e for lv, e, _ in self.lines if level is None or lv == level]


class FakeEntity:
    """A declared publisher, token, queryable or subscriber."""

    def __init__(self, kind: str, key: str, callback=None, **options) -> None:
        self.kind, self.key, self.callback, self.options = kind, key, callback, options
        self.sent: list[str] = []
        self.undeclared = False
        self.matching_status = SimpleNamespace(matching=False)

    def put(self, payload: str) -> None:
        self.sent.append(payload)

    def undeclare(self) -> None:
        self.undeclared = True


class FakeSession:
    """Enough of ``zenoh.Session`` for daemon.bus.link; ``entities`` by key."""

    def __init__(self) -> None:
        self.entities: dict[str, FakeEntity] = {}
        self.closed = False
        self.info = SimpleNamespace(peers_zid=lambda: ["p1", "p2"], routers_zid=lambda: [])

    def __enter__(self) -> FakeSession:
        return self

    def __exit__(self, *exc) -> None:
        self.closed = True

    def zid(self) -> str:
        return "fake-zid"

    def _declare(self, kind, key, callback=None, **options) -> FakeEntity:
        self.entities[key] = FakeEntity(kind, key, callback, **options)
        return self.entities[key]

    def declare_publisher(self, key, **options):
        return self._declare("publisher", key, **options)

    def declare_queryable(self, key, callback, **options):
        return self._declare("queryable", key, callback, **options)

    def declare_subscriber(self, key, callback):
        return self._declare("subscriber", key, callback)

    def liveliness(self):
        return SimpleNamespace(declare_token=lambda key: self._declare("token", key),
                               declare_subscriber=lambda key, callback, **options: self._declare(
                                   "liveliness_subscriber", key, callback, **options))


class FakeQuery:
    """A query with its key, parameters and the replies it got."""

    def __init__(self, key: str, **parameters: str) -> None:
        self.key_expr = key
        self.parameters = parameters
        self.replies: list[tuple[str, str]] = []
        self.errors: list[str] = []

    def reply(self, key: str, payload: str, **_options) -> None:
        self.replies.append((key, payload))

    def reply_err(self, payload: str, **_options) -> None:
        self.errors.append(payload)


def sample(text: str):
    """A received sample whose payload is ``text``."""
    return SimpleNamespace(payload=SimpleNamespace(to_string=lambda: text, to_bytes=lambda: text.encode()))
