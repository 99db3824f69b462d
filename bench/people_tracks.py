"""Track ids for bodies the benchmark knows by name (the renderer's or the composer's people), as the daemon's
landmark stage gives them: :class:`landmarks.tracks.PersonTracker` with a landmark *slot* per body that it
keeps while the body is found frame after frame, and a new slot after the body was lost (the daemon's
per-person ROI tracker lets go of a lost person; whoever is found next starts a free slot)."""

from __future__ import annotations

import numpy as np

from posed.landmarks import PersonTracker


class NamedBodies:
    """``update(t, [(name, landmarks), ...])`` -> the track id of each, in order; ``tracker`` for the rest."""

    def __init__(self) -> None:
        self.tracker = PersonTracker()
        self._slots: dict[str, int] = {}
        self._next = 0

    def update(self, t: float, seen: list[tuple[str, np.ndarray]]) -> list[int]:
        names = [n for n, _ in seen]
        for name in list(self._slots):
            if name not in names:
                del self._slots[name]
        for name in names:
            if name not in self._slots:
                self._next += 1
                self._slots[name] = self._next
        return self.tracker.update(t, [lms for _, lms in seen], [self._slots[n] for n in names])


def switches(ids: list[int | None]) -> int:
    """How often the track id changes between consecutive frames where the body was found (None: not found)."""
    seen = [i for i in ids if i is not None]
    return sum(1 for x, y in zip(seen, seen[1:], strict=False) if x != y)
