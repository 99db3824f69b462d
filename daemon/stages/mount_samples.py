"""The robot's camera poses on the daemon's clock, and which one is in force at a frame's capture time.

Both the publisher (the fall detector) and the fitting stage (the fit's vertical) ask the same question of the
same samples: :func:`in_force`. A sample says "from ``t`` (monotonic seconds, the capture clock) for
``valid_s`` seconds, gravity in the camera's axes was ``down`` and the optical centre ``height_m`` above the
floor". At capture time ``t`` the sample in force is the **latest one taken at or before** ``t`` (on equal
times, the one received last), and only while ``t <= t_sample + valid_s``: a newer sample supersedes an older
one even when the older one claimed to hold longer (the camera moved since), and once the newest sample before
a frame has expired nothing is in force (the other sources take over). A frame captured before every sample
has none.

:class:`MountSamples` is the bounded, time-ordered set the publisher keeps and hands to the fitting stage
through the ``mount`` mailbox (one writer, one reader; a frozen value, replaced as a whole).
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass

MAX_SAMPLES = 64          # at the robot's usual 10-30 Hz: 2-6 s of history, more than a frame spends in the pipeline


@dataclass(frozen=True)
class MountSample:
    """One camera pose from ``t`` (monotonic seconds) for ``valid_s`` seconds: ``down`` gravity in camera axes
    (unit; x image right, y image down, z forward), ``height_m`` the optical centre above the floor (m) or None,
    ``source`` what the robot said produced it (or None)."""

    t: float
    valid_s: float
    down: tuple[float, float, float]
    height_m: float | None = None
    source: str | None = None

    def covers(self, t: float) -> bool:
        """Whether this pose holds at capture time ``t``."""
        return self.t <= t <= self.t + self.valid_s


@dataclass(frozen=True)
class MountSamples:
    """The recent samples in time order (at most ``MAX_SAMPLES``, the oldest dropped first) and how many were
    accepted in all (``received``)."""

    samples: tuple[MountSample, ...] = ()
    received: int = 0

    def add(self, sample: MountSample, keep: int = MAX_SAMPLES) -> MountSamples:
        """These samples with ``sample`` put in its place by time (after those of equal time), the oldest
        dropped beyond ``keep``."""
        times = [s.t for s in self.samples]
        i = bisect.bisect_right(times, sample.t)
        out = (*self.samples[:i], sample, *self.samples[i:])
        return MountSamples(out[-keep:] if len(out) > keep else out, self.received + 1)

    def at(self, t: float) -> MountSample | None:
        """The sample in force at capture time ``t`` (:func:`in_force`)."""
        return in_force(self.samples, t)

    @property
    def newest(self) -> MountSample | None:
        return self.samples[-1] if self.samples else None


def in_force(samples: tuple[MountSample, ...], t: float) -> MountSample | None:
    """The sample in force at capture time ``t`` among ``samples`` (sorted by ``t``): the latest taken at or
    before ``t`` when it still holds, else None (module doc)."""
    i = bisect.bisect_right([s.t for s in samples], t)
    if i == 0:
        return None
    latest = samples[i - 1]
    return latest if latest.covers(t) else None
