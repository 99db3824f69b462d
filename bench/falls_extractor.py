"""The falls scenarios' 2D landmarks as another pose extractor gives them (``posed bench falls --extractor``).

The private recordings of issue 33 are 2D landmarks that MediaPipe Holistic extracted from real videos, as are
those of ``shared/data/falls/urfd_dev``. The scenarios give all 33 landmarks on every frame a person is in view;
Holistic does not. ``as_extractor(case, "holistic")`` makes a case's frames look like Holistic's, with every
number measured on urfd_dev's 27 clips (what the extractor does, not what the detector should do):

- on every frame with a person: the nose, shoulders, hips, knees and ankles, and nothing else of the face, the
  elbows (never, in 4,056 person frames) or the feet;
- each wrist on 9.3 % of those frames, in runs of 4.3 frames at 30 fps on average (0.14 s): a two-state chain
  with that share and that mean run;
- a fall's person lost on the floor until the recording ends in 3 of 8 falls, 0.13-0.53 s after the impact
  (``person_after_impact_s`` in labels.json): drawn per case from its name's seed, the delay uniform in
  0.1-0.55 s. A person found lying (never seen falling) is not lost: that recording would hold nobody.

"blazepose" leaves a case as it is (BlazePose gives all 33 landmarks, and posed's landmark stage retries a
lying person rotated).
"""

from __future__ import annotations

import zlib
from dataclasses import replace

import numpy as np

HOLISTIC_KEPT = (0, 11, 12, 23, 24, 25, 26, 27, 28)   # nose, shoulders, hips, knees, ankles
HOLISTIC_WRISTS = (15, 16)
WRIST_SHARE = 0.093          # share of urfd_dev's person frames with a given wrist
WRIST_RUN_S = 4.3 / 30.0     # mean length of a wrist's run (urfd_dev: 137 runs, 4.3 frames at 30 fps)
LOST_SHARE = 3.0 / 8.0       # urfd_dev: 3 of 8 falls lose the person on the floor for good
LOST_AFTER_S = (0.1, 0.55)   # ... 0.13-0.53 s after the impact

EXTRACTORS = {
    "blazepose": "all 33 landmarks, as the scenarios render them (posed's own landmark stage)",
    "holistic": "MediaPipe Holistic as on urfd_dev: nose, shoulders, hips, knees and ankles; a wrist on 9.3 % of "
                "frames; no elbows; 3 of 8 falls lose the person 0.1-0.55 s after the impact "
                "(bench.falls_extractor)",
}


def _wrist_chain(n: int, fps: float, rng: np.random.Generator) -> np.ndarray:
    """Which of ``n`` frames show the wrist: a two-state chain whose runs last WRIST_RUN_S on average and that
    is on WRIST_SHARE of the time."""
    p_off = min(1.0, 1.0 / max(WRIST_RUN_S * fps, 1.0))           # leaving a run
    p_on = min(1.0, p_off * WRIST_SHARE / (1.0 - WRIST_SHARE))    # entering one (stationary share WRIST_SHARE)
    on = bool(rng.random() < WRIST_SHARE)
    out = np.zeros(n, dtype=bool)
    for k in range(n):
        out[k] = on
        on = bool(rng.random() >= p_off) if on else bool(rng.random() < p_on)
    return out


def lost_from(case, rng: np.random.Generator) -> float | None:
    """The capture time from which a fall's person is no longer found, or None (kept to the end)."""
    truth = case.truth
    if truth.kind != "fall" or not truth.seen_falling or truth.t_impact is None:
        return None
    if rng.random() >= LOST_SHARE:
        return None
    return float(truth.t_impact + rng.uniform(*LOST_AFTER_S))


def as_extractor(case, extractor: str):
    """``case`` (:class:`bench.falls.Case`) with its frames' landmarks as ``extractor`` gives them
    (``EXTRACTORS``); the same case every run (seeded by its name)."""
    if extractor not in EXTRACTORS:
        raise ValueError(f"extractor {extractor!r} is not one of: {', '.join(EXTRACTORS)}")
    if extractor == "blazepose":
        return case
    rng = np.random.default_rng([zlib.crc32(case.name.encode()), 31])
    times = np.array([fr.t for fr in case.frames])
    fps = 1.0 / float(np.median(np.diff(times))) if len(times) > 1 else 10.0
    lost = lost_from(case, rng)
    wrists = [_wrist_chain(len(case.frames), fps, rng) for _ in HOLISTIC_WRISTS]
    frames = []
    for k, fr in enumerate(case.frames):
        lm = fr.landmarks
        if lm is not None and lost is not None and fr.t >= lost:
            lm = None
        if lm is not None:
            kept = np.full_like(lm, np.nan)
            kept[list(HOLISTIC_KEPT)] = lm[list(HOLISTIC_KEPT)]
            for i, shown in zip(HOLISTIC_WRISTS, wrists, strict=True):
                if shown[k]:
                    kept[i] = lm[i]
            lm = kept
        frames.append(replace(fr, landmarks=lm))
    return replace(case, frames=frames)
