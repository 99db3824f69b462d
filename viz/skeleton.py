"""The bones drawn between points: the 33 BlazePose landmarks and the fitted model's 13 joints.

Landmark indices are BlazePose's (landmarks.LANDMARK_NAMES); the model joints are ``fitting.JOINT_3D_NAMES``.
Each bone carries its side (``l``, ``r`` or ``c`` for the centre line) so a drawing can tell left from right
without colour alone (the right side is drawn dashed or thinner).
"""

from __future__ import annotations

# (from, to, side) between BlazePose landmark indices
LANDMARK_BONES: tuple[tuple[int, int, str], ...] = (
    (0, 1, "l"), (1, 2, "l"), (2, 3, "l"), (3, 7, "l"), (0, 4, "r"), (4, 5, "r"), (5, 6, "r"), (6, 8, "r"),
    (9, 10, "c"), (11, 12, "c"), (11, 13, "l"), (13, 15, "l"), (15, 17, "l"), (15, 19, "l"), (15, 21, "l"),
    (17, 19, "l"), (12, 14, "r"), (14, 16, "r"), (16, 18, "r"), (16, 20, "r"), (16, 22, "r"), (18, 20, "r"),
    (11, 23, "l"), (12, 24, "r"), (23, 24, "c"), (23, 25, "l"), (25, 27, "l"), (27, 29, "l"), (29, 31, "l"),
    (27, 31, "l"), (24, 26, "r"), (26, 28, "r"), (28, 30, "r"), (30, 32, "r"), (28, 32, "r"),
)

# (from, to, side) between fitted joints (fitting.JOINT_3D_NAMES)
MODEL_BONES: tuple[tuple[str, str, str], ...] = (
    ("left_shoulder", "right_shoulder", "c"), ("left_hip", "right_hip", "c"),
    ("mid_hip", "mid_shoulder", "c"),
    ("left_shoulder", "left_elbow", "l"), ("left_elbow", "left_wrist", "l"),
    ("right_shoulder", "right_elbow", "r"), ("right_elbow", "right_wrist", "r"),
    ("left_hip", "left_knee", "l"), ("left_knee", "left_ankle", "l"),
    ("right_hip", "right_knee", "r"), ("right_knee", "right_ankle", "r"),
)


def with_mid_shoulder(joints: dict[str, tuple[float, float, float]]) -> dict[str, tuple[float, float, float]]:
    """``joints`` plus ``mid_shoulder`` (the middle of the shoulders) when both shoulders are there."""
    out = dict(joints)
    if "left_shoulder" in joints and "right_shoulder" in joints:
        a, b = joints["left_shoulder"], joints["right_shoulder"]
        out["mid_shoulder"] = tuple((p + q) / 2.0 for p, q in zip(a, b, strict=True))
    return out
