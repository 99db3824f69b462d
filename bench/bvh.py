"""Read a BVH motion-capture file (numpy only) and turn it into MediaPipe-style 33x5 landmarks.

BVH: a HIERARCHY of joints (OFFSET from the parent, CHANNELS per joint) and MOTION frames. A joint's local
rotation is the product of its rotation channels in the order listed (``Zrotation Yrotation Xrotation`` ->
Rz @ Ry @ Rx); its world position is ``parent_position + parent_rotation @ offset``. The CMU files are
Y up, +Z forward, +X the subject's left, in CMU units (``CMU_UNIT_M`` = 0.0564 m, i.e. inches / 0.45).

``cmu_landmark_world`` maps the CMU skeleton (subject 131's naming) to world points in the scenario frame of
:mod:`bench.falls_body` (metres, z up) so the same cameras render it.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

import numpy as np

CMU_UNIT_M = 2.54 / 100.0 / 0.45   # 0.05644 m per CMU unit


@dataclass
class Joint:
    name: str
    parent: int
    offset: np.ndarray
    channels: list[str]
    end_site: np.ndarray | None = None


@dataclass
class Motion:
    joints: list[Joint]
    frame_time: float
    data: np.ndarray   # frames x channels

    @property
    def fps(self) -> float:
        return 1.0 / self.frame_time

    def index(self, name: str) -> int:
        for i, j in enumerate(self.joints):
            if j.name == name:
                return i
        raise KeyError(f"no joint {name!r} in this BVH; joints: {', '.join(j.name for j in self.joints)}")


def read_bvh(path: str | os.PathLike) -> Motion:
    """Parse a BVH file; raises ValueError naming the line that is wrong."""
    with open(path, encoding="utf-8", errors="replace") as fh:
        lines = fh.read().splitlines()
    joints: list[Joint] = []
    stack: list[int] = []
    pending_end = False
    i = 0
    while i < len(lines):
        tok = lines[i].split()
        i += 1
        if not tok:
            continue
        key = tok[0]
        if key in ("ROOT", "JOINT"):
            joints.append(Joint(tok[1], stack[-1] if stack else -1, np.zeros(3), []))
        elif key == "End":
            pending_end = True
        elif key == "{":
            if pending_end:
                stack.append(-2)
            else:
                stack.append(len(joints) - 1)
        elif key == "}":
            if not stack:
                raise ValueError(f"{path}:{i}: unbalanced '}}'")
            top = stack.pop()
            if top == -2:
                pending_end = False
        elif key == "OFFSET":
            off = np.array([float(v) for v in tok[1:4]])
            if pending_end:
                joints[stack[-2] if stack[-1] == -2 else stack[-1]].end_site = off
            else:
                joints[-1].offset = off
        elif key == "CHANNELS":
            joints[-1].channels = tok[2:2 + int(tok[1])]
        elif key == "MOTION":
            break
        elif key == "HIERARCHY":
            continue
        else:
            raise ValueError(f"{path}:{i}: unexpected {key!r} in the hierarchy")
    try:
        n_frames = int(lines[i].split(":")[1])
        frame_time = float(lines[i + 1].split(":")[1])
    except (IndexError, ValueError):
        raise ValueError(f"{path}:{i + 1}: expected 'Frames: N' and 'Frame Time: T' after MOTION") from None
    n_ch = sum(len(j.channels) for j in joints)
    rows = [r for r in lines[i + 2:i + 2 + n_frames] if r.strip()]
    data = np.array([[float(v) for v in r.split()] for r in rows])
    if data.shape != (n_frames, n_ch):
        raise ValueError(f"{path}: expected {n_frames} frames of {n_ch} channels, got {data.shape}")
    return Motion(joints, frame_time, data)


def _axis_rot(axis: str, deg: np.ndarray) -> np.ndarray:
    a = np.radians(deg)
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(a), np.zeros_like(a)
    if axis == "X":
        m = [[o, z, z], [z, c, -s], [z, s, c]]
    elif axis == "Y":
        m = [[c, z, s], [z, o, z], [-s, z, c]]
    else:
        m = [[c, -s, z], [s, c, z], [z, z, o]]
    return np.moveaxis(np.array(m), [0, 1], [-2, -1])


def forward_kinematics(motion: Motion, frames: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """World positions (F, J, 3), rotations (F, J, 3, 3) and end-site positions (F, J, 3; NaN where none),
    in BVH units and axes."""
    data = motion.data if frames is None else motion.data[frames]
    f = data.shape[0]
    nj = len(motion.joints)
    pos = np.zeros((f, nj, 3))
    rot = np.zeros((f, nj, 3, 3))
    ends = np.full((f, nj, 3), np.nan)
    col = 0
    for k, j in enumerate(motion.joints):
        local = np.broadcast_to(np.eye(3), (f, 3, 3)).copy()
        trans = np.zeros((f, 3))
        for ch in j.channels:
            v = data[:, col]
            col += 1
            if ch.endswith("position"):
                trans[:, "XYZ".index(ch[0])] = v
            else:
                local = local @ _axis_rot(ch[0], v)
        if j.parent < 0:
            pos[:, k] = j.offset + trans
            rot[:, k] = local
        else:
            pos[:, k] = pos[:, j.parent] + np.einsum("fij,j->fi", rot[:, j.parent], j.offset)
            rot[:, k] = rot[:, j.parent] @ local
        if j.end_site is not None:
            ends[:, k] = pos[:, k] + np.einsum("fij,j->fi", rot[:, k], j.end_site)
    return pos, rot, ends


# CMU (Y up, +Z forward, +X left) -> scenario world (x, y, z up): (x, y, z) -> (x, -z, y), a proper rotation.
_TO_WORLD = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


def cmu_landmark_world(motion: Motion, frames: np.ndarray | None = None, unit_m: float = CMU_UNIT_M
                       ) -> list[dict[str, np.ndarray]]:
    """Per frame, the world points (metres, z up, feet on z = 0 at the first frame) that
    :meth:`bench.falls_body.WorldCamera.project` renders, named as in :data:`bench.falls_body.MP` plus
    ``pelvis``."""
    pos, rot, ends = forward_kinematics(motion, frames)
    idx = motion.index
    world = np.einsum("ij,fkj->fki", _TO_WORLD, pos) * unit_m
    ends_w = np.einsum("ij,fkj->fki", _TO_WORLD, ends) * unit_m
    rot_w = np.einsum("ij,fkjl->fkil", _TO_WORLD, rot)
    floor = float(np.nanmin(world[0, :, 2]))
    world[..., 2] -= floor
    ends_w[..., 2] -= floor
    out = []
    for f in range(world.shape[0]):
        p = {}

        def at(name, f=f):
            return world[f, idx(name)]

        for side, cmu in (("left", "Left"), ("right", "Right")):
            p[f"{side}_shoulder"] = at(f"{cmu}Shoulder")
            p[f"{side}_elbow"] = at(f"{cmu}Elbow")
            p[f"{side}_wrist"] = at(f"{cmu}Wrist")
            p[f"{side}_hip"] = at(f"{cmu}Hip")
            p[f"{side}_knee"] = at(f"{cmu}Knee")
            p[f"{side}_ankle"] = at(f"{cmu}Ankle")
            toe = ends_w[f, idx(f"{cmu}Toe")]
            toe_base = at(f"{cmu}Toe")
            ankle = p[f"{side}_ankle"]
            p[f"{side}_foot_index"] = toe
            p[f"{side}_heel"] = ankle + 0.6 * (ankle - toe_base) + np.array([0.0, 0.0, -0.04])
            hand = ends_w[f, idx(f"{side[0]}hand")] if not math.isnan(ends_w[f, idx(f"{side[0]}hand"), 0]) else None
            fingers = ends_w[f, idx(f"{side[0].upper()}Fingers")]
            thumb = ends_w[f, idx(f"{side[0].upper()}Thumb")]
            wrist = p[f"{side}_wrist"]
            tip = fingers if hand is None else hand
            p[f"{side}_pinky"] = 0.5 * (wrist + tip) + 0.2 * (tip - thumb)
            p[f"{side}_index"] = tip
            p[f"{side}_thumb"] = thumb
        head = at("Head")
        top = ends_w[f, idx("Head")]
        r_head = rot_w[f, idx("Head")] @ _TO_WORLD.T   # head axes in world (columns: left, up, forward)
        left, up, fwd = r_head[:, 0], r_head[:, 1], r_head[:, 2]
        centre = 0.5 * (head + top)
        p["nose"] = centre + 0.09 * fwd - 0.02 * up
        for side, sgn in (("left", 1.0), ("right", -1.0)):
            p[f"{side}_eye_inner"] = centre + 0.08 * fwd + 0.015 * up + sgn * 0.015 * left
            p[f"{side}_eye"] = centre + 0.075 * fwd + 0.015 * up + sgn * 0.032 * left
            p[f"{side}_eye_outer"] = centre + 0.068 * fwd + 0.015 * up + sgn * 0.045 * left
            p[f"{side}_ear"] = centre + 0.075 * sgn * left
            p[f"mouth_{side}"] = centre + 0.075 * fwd - 0.045 * up + sgn * 0.022 * left
        p["pelvis"] = 0.5 * (p["left_hip"] + p["right_hip"])
        out.append(p)
    return out
