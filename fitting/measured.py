"""What one frame's fit measured: the one rule every view, topic and file of posed applies before it shows a
joint angle or a joint position as a fact.

* A **body landmark** (one of the fit's 12) is measured on a frame when its x, y and visibility are finite,
  its visibility is at least the fit's ``visibility_drop`` (0.3 by default: below it the fit does not use the
  landmark), and its presence, when the landmark carries one, is at least the same threshold (MediaPipe's
  presence: how likely the landmark is inside the image at all).
* A **joint position** (``joints_3d``) is measured when its own landmark is; ``mid_hip`` when both hips are.
* A **joint angle** is the rotation between two body segments: it is measured when every landmark that places
  both segments is (``NEEDS``): an elbow needs its shoulder, elbow and wrist; a knee its hip, knee and ankle.
  The trunk and the pelvis are placed together by both shoulders and both hips (the torso): the trunk's
  angles, the body's orientation to the camera (``theta_bd``, ``phi_bd``, ``psi_bd``) and, with its elbow or
  knee, a shoulder's or a hip's angles need all four. The fit runs with one of the four missing, but then
  places the pelvis and trunk from the model's guess: on the real UR Fall recording urfd_04, the 32 frames
  with a shoulder missing have body pitch jumping between -180 and +85 degrees from one frame to the next
  and trunk flexion between 0 and 100.
* An angle the refinement held at a joint limit (``at_limit`` in the result: the fit wanted it further than
  the model allows; a straight knee or elbow at 0 excepted) is the clamp's value, not a measurement.
* The angles the model holds fixed (``FIXED``: head, hip rotation, ankles; no landmark the fit uses observes
  them) are never measured. A failed fit measured nothing.

Everything else the fit reports for an unmeasured joint is the model's guess (held from the previous frame or
at a neutral value), never a measurement: a drawing leaves it out or marks it, a table says "not measured", a
topic leaves it out. The fit writes what it measured into each result (``FitResult.measured``, JSON key
``measured``); a result written before that field existed is judged by the same rule from its ``missing``
landmarks (and ``unobserved`` variables).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from posed.fitting.result import BODY_ANGLE_NAMES, JOINT_3D_NAMES, JOINT_ANGLE_NAMES

VISIBILITY_DROP = 0.3   # FitConfig.visibility_drop's default: the threshold when the caller has no config

# the 12 body landmarks by name, and their BlazePose index (fitting.BODY_LANDMARKS: the same order)
BODY_LANDMARK_NAMES = JOINT_3D_NAMES[1:]
BODY_LANDMARK_INDEX = dict(zip(BODY_LANDMARK_NAMES, (11, 12, 13, 14, 15, 16, 23, 24, 25, 26, 27, 28), strict=True))

TORSO = ("left_shoulder", "right_shoulder", "left_hip", "right_hip")
FIXED = ("theta_hd", "psi_hd", "psi_hp_l", "psi_hp_r", "theta_an_l", "phi_an_l", "theta_an_r", "phi_an_r")


def _limb(side: str) -> dict[str, tuple[str, ...]]:
    s = "left" if side == "l" else "right"
    return {f"theta_sh_{side}": (*TORSO, f"{s}_elbow"), f"phi_sh_{side}": (*TORSO, f"{s}_elbow"),
            f"theta_el_{side}": (f"{s}_shoulder", f"{s}_elbow", f"{s}_wrist"),
            f"theta_hp_{side}": (*TORSO, f"{s}_knee"), f"phi_hp_{side}": (*TORSO, f"{s}_knee"),
            f"theta_kn_{side}": (f"{s}_hip", f"{s}_knee", f"{s}_ankle")}


# the landmarks each measurable angle needs (joint angles and the body angles, by the result's names)
NEEDS: dict[str, tuple[str, ...]] = {
    **dict.fromkeys(("theta_tr", "phi_tr", "psi_tr", *BODY_ANGLE_NAMES), TORSO), **_limb("l"), **_limb("r"),
}
# every angle name a result carries (joint angles, then the body angles)
ANGLE_NAMES = JOINT_ANGLE_NAMES + BODY_ANGLE_NAMES
# the landmarks each joint position needs
JOINT_NEEDS: dict[str, tuple[str, ...]] = {"mid_hip": ("left_hip", "right_hip"),
                                           **{n: (n,) for n in BODY_LANDMARK_NAMES}}


def measured_landmarks(landmarks: Any, visibility_drop: float = VISIBILITY_DROP) -> tuple[str, ...]:
    """The body landmarks measured on a frame of 33 ``[x_px, y_px, z, visibility, presence]`` rows (NaN or a
    missing column: unknown), in ``BODY_LANDMARK_NAMES`` order; none for None."""
    if landmarks is None:
        return ()
    lm = np.asarray(landmarks, dtype=np.float64)
    if lm.ndim != 2 or lm.shape[0] != 33 or lm.shape[1] < 4:
        raise ValueError(f"landmarks must be 33 rows [x_px, y_px, z, visibility(, presence)], got shape "
                         f"{lm.shape}")
    out = []
    for name, i in BODY_LANDMARK_INDEX.items():
        x, y, vis = lm[i, 0], lm[i, 1], lm[i, 3]
        presence = lm[i, 4] if lm.shape[1] > 4 else np.nan
        if np.isfinite(x) and np.isfinite(y) and np.isfinite(vis) and vis >= visibility_drop \
                and not (np.isfinite(presence) and presence < visibility_drop):
            out.append(name)
    return tuple(out)


@dataclass(frozen=True)
class Measured:
    """What a frame's fit measured: body ``landmarks``, ``angles`` (joint angles and body angles by the
    result's names) and ``joints`` (``joints_3d`` keys), each in the result's own order."""

    landmarks: tuple[str, ...] = ()
    angles: tuple[str, ...] = ()
    joints: tuple[str, ...] = ()

    @classmethod
    def from_landmarks(cls, seen: Iterable[str], unobserved: Iterable[str] = ()) -> Measured:
        """The rule applied to the measured body landmarks ``seen`` (``unobserved``: variables a result written
        before this field listed as not observed, left out too)."""
        seen_set = set(seen)
        unknown = seen_set - set(BODY_LANDMARK_NAMES)
        if unknown:
            raise ValueError(f"unknown body landmark(s) {', '.join(sorted(unknown))}; known: "
                             f"{', '.join(BODY_LANDMARK_NAMES)}")
        hidden = set(unobserved)
        return cls(landmarks=tuple(n for n in BODY_LANDMARK_NAMES if n in seen_set),
                   angles=tuple(n for n in ANGLE_NAMES
                                if n in NEEDS and n not in hidden and seen_set.issuperset(NEEDS[n])),
                   joints=tuple(n for n in JOINT_3D_NAMES if seen_set.issuperset(JOINT_NEEDS[n])))

    @classmethod
    def of_legacy(cls, extra: Mapping[str, Any]) -> Measured:
        """The rule applied to a result written before ``measured`` existed: its ``missing`` landmarks (the
        ones the fit could not use) and ``unobserved`` variables."""
        missing = set(extra.get("missing") or ())
        return cls.from_landmarks((n for n in BODY_LANDMARK_NAMES if n not in missing),
                                  [*(extra.get("unobserved") or ()), *(extra.get("at_limit") or ())])

    def angle(self, name: str) -> bool:
        return name in self.angles

    def joint(self, name: str) -> bool:
        return name in self.joints

    def to_json(self) -> dict[str, list[str]]:
        return {"landmarks": list(self.landmarks), "angles": list(self.angles), "joints_3d": list(self.joints)}

    @classmethod
    def from_json(cls, obj: Any) -> Measured:
        """Parse the JSON object ``measured``; raises ValueError naming what is wrong."""
        if not isinstance(obj, dict):
            raise ValueError(f"measured must be an object with landmarks, angles and joints_3d, got {obj!r}")
        parts = {}
        for key, known in (("landmarks", BODY_LANDMARK_NAMES), ("angles", ANGLE_NAMES),
                           ("joints_3d", JOINT_3D_NAMES)):
            v = obj.get(key, [])
            if not isinstance(v, list) or not all(isinstance(n, str) for n in v):
                raise ValueError(f"measured.{key} must be a list of names, got {v!r}")
            bad = [n for n in v if n not in known]
            if bad:
                raise ValueError(f"measured.{key}: unknown name(s) {', '.join(bad)}; known: {', '.join(known)}")
            parts[key] = tuple(n for n in known if n in v)
        return cls(parts["landmarks"], parts["angles"], parts["joints_3d"])
