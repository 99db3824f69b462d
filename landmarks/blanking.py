"""A followed person's body as pixels, drawn from their 33 landmarks: :func:`body_mask`.

BlazePose's detector sees the most prominent person: with one person in full view its scores for a second,
smaller one fall below 0.05 (0.84 for them alone). So :class:`~landmarks.people.MultiPoseLandmarker` paints
the people it follows out of the image its detector looks at (never out of what the landmark passes see):
their landmark box, and, where someone was just lost beside them, only their body. A box with the arms
spread is mostly empty space, and a person who was hidden behind them reappears in it. The body is the head
(a disc around the face's landmarks), the trunk (the shoulder-hip quad) and the limbs (the segments between
landmarks, hands and feet included), each drawn ``LIMB_WIDTH`` times the person's torso length wide (mid-shoulder to
mid-hip). Widths from adult body proportions: Drillis & Contini's segment lengths put shoulder to hip at
about 0.29 of the stature and the head (chin to crown) at about 0.13; a thigh is about 16 cm broad (0.09 of a
1.75 m stature). So a thigh is about 0.3 torso lengths wide and the head about 0.45 long; the widths below
add the landmarks' own error (about 0.1 torso lengths) as the margin.
"""

from __future__ import annotations

import cv2
import numpy as np

from posed.landmarks.sides import torso_length as sides_torso_length

LIMB_WIDTH = 0.4         # limb drawn this wide: a thigh's breadth (0.3 torso lengths) plus the landmarks' error
HEAD_RADIUS = 0.35       # disc around the face's landmarks: half a head's length (0.45 / 2) plus the error
MIN_TORSO_PX = 4.0       # a body whose torso is shorter (or not finite) is drawn at this size

HEAD = tuple(range(11))                                        # nose, eyes, ears, mouth
TRUNK = (11, 12, 24, 23)                                       # shoulders, hips (a quad, in order)
LIMBS = ((11, 13), (13, 15), (15, 17), (15, 19), (15, 21),     # left arm and hand
         (12, 14), (14, 16), (16, 18), (16, 20), (16, 22),     # right arm and hand
         (23, 25), (25, 27), (27, 29), (27, 31), (29, 31),     # left leg and foot
         (24, 26), (26, 28), (28, 30), (28, 32), (30, 32),     # right leg and foot
         (11, 12), (23, 24), (11, 23), (12, 24))               # the trunk's edges


def torso_length(landmarks: np.ndarray) -> float:
    """Mid-shoulder to mid-hip distance in pixels (:func:`landmarks.sides.torso_length`; ``MIN_TORSO_PX`` when it
    cannot be measured)."""
    d = sides_torso_length(np.asarray(landmarks, dtype=np.float64)[:, :2])
    return d if np.isfinite(d) and d > MIN_TORSO_PX else MIN_TORSO_PX


def body_mask(shape: tuple[int, int], landmarks: np.ndarray) -> np.ndarray:
    """(H, W) bool: the pixels of one person's body (see the module doc) in an image of ``shape``."""
    xy = np.asarray(landmarks, dtype=np.float64)[:, :2]
    mask = np.zeros(shape[:2], np.uint8)
    torso = torso_length(landmarks)
    width = max(1, round(LIMB_WIDTH * torso))
    ok = np.isfinite(xy).all(axis=1)
    pts = np.where(ok[:, None], np.round(xy), 0).astype(np.int32)
    for i, j in LIMBS:
        if ok[i] and ok[j]:
            cv2.line(mask, (int(pts[i, 0]), int(pts[i, 1])), (int(pts[j, 0]), int(pts[j, 1])), 1, width)
    if ok[list(TRUNK)].all():
        cv2.fillConvexPoly(mask, pts[list(TRUNK)], 1)
    face = [i for i in HEAD if ok[i]]
    if face:
        centre = xy[face].mean(axis=0)
        cv2.circle(mask, (int(round(centre[0])), int(round(centre[1]))), max(1, round(HEAD_RADIUS * torso)), 1, -1)
    return mask > 0
