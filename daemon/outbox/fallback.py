"""Where fall-event messages wait when the state directory cannot take them (read-only, full, gone).

The journal (:mod:`daemon.outbox.journal`) keeps such messages in memory and republishes them until they are
acknowledged; memory alone dies with the process. This file keeps them across a restart of the daemon: one
JSON object per line (the message as :meth:`StoredEvent.to_json` plus ``wall``), rewritten whole (write to a
temporary sibling, fsync, rename) whenever what waits changes, removed once the journal holds every message
again. At start-up the journal takes back what the file holds before anything else.

Its folder (:func:`fallback_dir`): ``$RUNTIME_DIRECTORY`` (systemd's ``RuntimeDirectory=posed``, a tmpfs
under ``/run``), else ``/run/posed`` when ``/run`` is writable, else ``/dev/shm``, else the temporary folder.
It is a tmpfs on purpose: it survives a restart of the daemon, not a power loss, and does not depend on the
disk that failed. The file name holds a hash of the state directory, so two daemons never share one; mode 0600
(fall events are health data).
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
from collections.abc import Iterable
from pathlib import Path

from posed.daemon.outbox.journal_rows import StoredEvent
from posed.daemon.outbox.private import write_private
from posed.falls.event import FallEvent

# StoredEvent's fields besides the message (a file written by an older posed lacks the newer ones: None)
DELIVERY_FIELDS = ("published_at", "acked_at", "acked_by", "hooks_done_at", "hooks_outcome")


def fallback_dir(environ: dict | None = None) -> Path:
    """The folder of the fallback file (see the module docstring for the order)."""
    env = os.environ if environ is None else environ
    if env.get("RUNTIME_DIRECTORY"):
        return Path(env["RUNTIME_DIRECTORY"].split(":")[0])
    for candidate in (Path("/run/posed"), Path("/dev/shm")):
        parent = candidate if candidate.exists() else candidate.parent
        if os.access(parent, os.W_OK | os.X_OK):
            return candidate
    return Path(tempfile.gettempdir())


def fallback_path(state_dir: Path, environ: dict | None = None) -> Path:
    """The fallback file of the daemon whose state directory is ``state_dir``."""
    key = hashlib.sha256(str(Path(state_dir).absolute()).encode()).hexdigest()[:16]
    return fallback_dir(environ) / f"posed-unstored-events-{key}.jsonl"


class FallbackStore:
    """The fallback file of one journal; every method is quiet on failure and returns what happened."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self.last_error = ""

    def save(self, items: Iterable[StoredEvent]) -> bool:
        """Replace the file's content with ``items``; False (and ``last_error``) when it cannot be written."""
        lines = [json.dumps(dict(item.to_json(), wall=item.wall), separators=(",", ":")) for item in items]
        try:
            self.path.parent.mkdir(mode=0o700, parents=True, exist_ok=True)
            write_private(self.path, "\n".join(lines) + ("\n" if lines else ""))
        except OSError as exc:
            self.last_error = f"cannot write {self.path}: {exc}"
            return False
        self.last_error = ""
        return True

    def clear(self) -> None:
        try:
            self.path.unlink()
        except FileNotFoundError:
            pass
        except OSError as exc:
            self.last_error = f"cannot remove {self.path}: {exc}"

    def load(self) -> list[StoredEvent]:
        """What the file holds (an unreadable line is skipped); [] when there is no file."""
        try:
            text = self.path.read_text()
        except FileNotFoundError:
            return []
        except OSError as exc:
            self.last_error = f"cannot read {self.path}: {exc}"
            return []
        out = []
        for line in text.splitlines():
            try:
                obj = json.loads(line)
                wall = float(obj.pop("wall"))
                delivery = {k: obj.pop(k, None) for k in DELIVERY_FIELDS}
                out.append(StoredEvent(FallEvent.from_json(obj), wall, **delivery))
            except (ValueError, KeyError, TypeError):
                continue
        return out
