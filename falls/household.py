"""Who is who (``falls.household``): each person in view recognised as a household member, a visitor, or not yet
known, from their stature (:mod:`falls.stature`) measured while they stand upright.

Per person (track id) the last ``KEEP_SAMPLES`` stature samples are kept; from ``MIN_SAMPLES`` on (a second of
standing at 10 fps), their median is compared with each member's configured height:

* within ``TOLERANCE_M`` of one member, and nearer to them than to any other by ``MARGIN_M``: that member, with
  ``sure`` = 1 - |difference| / ``TOLERANCE_M``;
* further than ``TOLERANCE_M`` from every member: a visitor (``member`` None, ``visitor`` true);
* otherwise (two members too alike, or between): not known.

Why these values: the shoulder height is 0.818 of the stature on average with a spread between adults of about
1.5 % (Drillis and Contini 1966; 2.5 cm at 1.65 m); the measurement with a measured mount errs by about 1-2 %
of the distance per degree of tilt error (3-5 cm at 3 m); a person's stature at home varies by 1-2 cm over a
day and by shoes. ``TOLERANCE_M`` = 0.07 m is about twice their combined spread; ``MARGIN_M`` = 0.03 m keeps
two members closer than that from being told apart by noise. Two members of the same height are not told
apart (say so in the config: the status lists them as not known).

Nothing is kept across restarts and nothing from images: only the stature, a number, per track.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from posed.falls.config import HouseholdMember

TOLERANCE_M = 0.07
MARGIN_M = 0.03
MIN_SAMPLES = 10
KEEP_SAMPLES = 100


class Household:
    """The household's members and what is measured of each person (module doc)."""

    def __init__(self, members: tuple[HouseholdMember, ...]) -> None:
        self.members = tuple(members)
        self._samples: dict[object, deque[float]] = {}

    def __bool__(self) -> bool:
        return bool(self.members)

    def observe(self, key: object, stature_m: float) -> None:
        """One standing frame's stature of the person ``key``."""
        self._samples.setdefault(key, deque(maxlen=KEEP_SAMPLES)).append(float(stature_m))

    def rename(self, old: object, new: object) -> None:
        """The person ``old`` is now known as ``new`` (a new track id matched back)."""
        if old in self._samples:
            self._samples[new] = self._samples.pop(old)

    def forget(self, key: object) -> None:
        self._samples.pop(key, None)

    def who(self, key: object) -> dict:
        """``{"member": name or None, "visitor": bool, "sure": 0..1 or None, "stature_m": median or None,
        "samples": n}`` for the person ``key``."""
        samples = self._samples.get(key, ())
        out = {"member": None, "visitor": False, "sure": None, "samples": len(samples),
               "stature_m": round(float(np.median(samples)), 3) if samples else None}
        if len(samples) < MIN_SAMPLES or not self.members:
            return out
        h = float(np.median(samples))
        gaps = sorted((abs(h - m.height_m), i) for i, m in enumerate(self.members))
        best, i = gaps[0]
        if best > TOLERANCE_M:
            out["visitor"] = True
            out["sure"] = round(min(1.0, (best - TOLERANCE_M) / TOLERANCE_M), 3)
        elif len(gaps) == 1 or gaps[1][0] - best >= MARGIN_M:
            out["member"] = self.members[i].name
            out["sure"] = round(1.0 - best / TOLERANCE_M, 3)
        return out

    def rank(self, key: object) -> int | None:
        """The member's place in the configured list (0 first) for a person recognised as one, else None."""
        name = self.who(key)["member"]
        return None if name is None else next(i for i, m in enumerate(self.members) if m.name == name)
