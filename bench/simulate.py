"""Simulated people with ground truth: poses, motion sequences and their 2D landmarks (33 x 5).

* :data:`PAPER_POSES`: the six poses of the paper's section 4.1 (stand and raise arms to the front, raise
  arms up, walk with the left leg in front, bend down to grab, sit on a chair, kneel down), pelvis upright
  (theta_bd = phi_bd = 0, inside the paper's Table 1 bounds); the body yaw psi_bd is chosen by the caller
  (the paper uses 20..40 degrees).
* :data:`FLOOR_POSES`: lying, sitting-on-the-floor and fallen poses (body tilted up to and past 90 degrees).
* :data:`SEQUENCE_NAMES`: short motions as functions of time (stand -> sit, squat, falls forward /
  backward / sideways, lying down slowly, sitting down on the floor, standing still).
* :func:`render`: a pose -> (33, 5) ``[x_px, y_px, z, visibility, presence]`` in MediaPipe order
  (interfaces.md section 1), orthographic or pinhole camera, optional Gaussian pixel noise with a seed.

The person stands on a floor (the lowest landmark touches it); the camera is level (gravity is image down),
at ``LevelCamera.height_m`` above the floor. Angles are degrees everywhere (Vicon polarity, see
:mod:`fitting.kinematics`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

from posed.camera_model import Intrinsics
from posed.fitting import BodyDimensions, FitResult, Pose, joints_3d, landmarks_camera

__all__ = [
    "FLOOR_POSES", "PAPER_POSES", "POSES", "SEQUENCE_NAMES", "LevelCamera", "Placement", "Pose", "Sequence", "body_dimensions",
    "ground_truth", "pose", "render", "render_sequence", "sequence",
]


def body_dimensions(height_m: float = 1.60) -> BodyDimensions:
    """Link lengths from body height (Drillis & Contini ratios, see :mod:`fitting.body`)."""
    return BodyDimensions.from_height(height_m)


# --- poses ---------------------------------------------------------------------------------------------

def _pose(theta_bd: float = 0.0, phi_bd: float = 0.0, **joints: float) -> Pose:
    return Pose(joints, theta_bd=theta_bd, phi_bd=phi_bd)


# The paper's six (section 4.1). Arms: theta_sh flexion, phi_sh adduction (negative = arm out to the side).
_PAPER = {
    "stand_arms_front": _pose(theta_sh_l=90, theta_sh_r=85, phi_sh_l=-5, phi_sh_r=-3, theta_el_l=10, theta_el_r=5,
                              theta_tr=3, theta_hp_l=2, theta_hp_r=0, theta_kn_l=3, theta_kn_r=2,
                              phi_hp_l=-3, phi_hp_r=-3),
    "stand_arms_up": _pose(theta_sh_l=165, theta_sh_r=170, phi_sh_l=-12, phi_sh_r=-10, theta_el_l=8, theta_el_r=5,
                           theta_tr=-4, theta_hp_l=0, theta_hp_r=3, theta_kn_l=2, theta_kn_r=4,
                           phi_hp_l=-4, phi_hp_r=-2),
    "walk_left_forward": _pose(theta_tr=5, psi_tr=-6, theta_hp_l=25, theta_kn_l=10, theta_hp_r=-10, theta_kn_r=15,
                               phi_hp_l=-2, phi_hp_r=-4, theta_sh_l=-15, theta_el_l=15, theta_sh_r=20,
                               theta_el_r=25, phi_sh_l=-8, phi_sh_r=-8),
    "bend_grab": _pose(theta_tr=55, phi_tr=3, theta_hp_l=30, theta_hp_r=32, theta_kn_l=25, theta_kn_r=28,
                       phi_hp_l=-5, phi_hp_r=-6, theta_sh_l=60, theta_sh_r=75, theta_el_l=10, theta_el_r=20,
                       phi_sh_l=-6, phi_sh_r=-4),
    "sit_chair": _pose(theta_tr=4, theta_hp_l=88, theta_kn_l=85, theta_hp_r=86, theta_kn_r=80,
                       phi_hp_l=-6, phi_hp_r=-5, theta_sh_l=25, theta_el_l=60, theta_sh_r=20, theta_el_r=65,
                       phi_sh_l=-5, phi_sh_r=-4),
    "kneel": _pose(theta_tr=5, theta_hp_l=85, theta_kn_l=88, theta_hp_r=-10, theta_kn_r=90,
                   phi_hp_l=-4, phi_hp_r=-3, theta_sh_l=10, theta_el_l=20, theta_sh_r=15, theta_el_r=15,
                   phi_sh_l=-10, phi_sh_r=-10),
}
PAPER_POSES = tuple(_PAPER)

# On the floor. The lumbar joint is kept straight when lying (see docs/body-model.md: the pelvis tilt is not
# observable and the fit's prior assumes a neutral lumbar spine unless the torso is upright).
_FLOOR = {
    "lying_back": _pose(theta_bd=-90, theta_hp_l=3, theta_hp_r=5, theta_kn_l=5, theta_kn_r=8,
                        phi_hp_l=-8, phi_hp_r=-6, theta_sh_l=5, theta_sh_r=10, phi_sh_l=-20, phi_sh_r=-25,
                        theta_el_l=10, theta_el_r=15),
    "lying_front": _pose(theta_bd=90, theta_hp_l=2, theta_hp_r=5, theta_kn_l=10, theta_kn_r=5,
                         phi_hp_l=-10, phi_hp_r=-5, theta_sh_l=150, theta_sh_r=5, phi_sh_l=-20, phi_sh_r=-15,
                         theta_el_l=30, theta_el_r=10),
    "lying_side": _pose(phi_bd=80, theta_hp_l=30, theta_kn_l=40, theta_hp_r=20, theta_kn_r=30,
                        theta_sh_l=70, theta_el_l=40, theta_sh_r=40, theta_el_r=60, phi_hp_r=5),
    "fetal": _pose(phi_bd=-80, theta_hp_l=80, theta_kn_l=110, theta_hp_r=85, theta_kn_r=115,
                   theta_sh_l=70, theta_el_l=100, theta_sh_r=60, theta_el_r=90),
    "sitting_floor": _pose(theta_tr=10, theta_hp_l=90, theta_hp_r=88, theta_kn_l=5, theta_kn_r=3,
                           phi_hp_l=-10, phi_hp_r=-8, theta_sh_l=15, theta_sh_r=10, phi_sh_l=-20, phi_sh_r=-18,
                           theta_el_l=10, theta_el_r=5),
    "sitting_floor_knees_up": _pose(theta_tr=15, theta_hp_l=110, theta_hp_r=105, theta_kn_l=120, theta_kn_r=115,
                                    phi_hp_l=-10, phi_hp_r=-12, theta_sh_l=50, theta_sh_r=45, theta_el_l=60,
                                    theta_el_r=65),
    "sitting_floor_leaning_back": _pose(theta_bd=-25, theta_hp_l=65, theta_hp_r=70, theta_kn_l=40, theta_kn_r=20,
                                        phi_hp_l=-8, phi_hp_r=-8, theta_sh_l=-30, theta_sh_r=-35,
                                        phi_sh_l=-15, phi_sh_r=-15, theta_el_l=5, theta_el_r=5),
    "fallen_forward": _pose(theta_bd=80, theta_hp_l=10, theta_hp_r=30, theta_kn_l=20, theta_kn_r=60,
                            phi_hp_l=-10, phi_hp_r=-15, theta_sh_l=120, theta_sh_r=100, theta_el_l=30,
                            theta_el_r=40, phi_sh_l=-20, phi_sh_r=-25),
    "fallen_backward": _pose(theta_bd=-75, theta_hp_l=40, theta_hp_r=30, theta_kn_l=70, theta_kn_r=50,
                             phi_hp_l=-10, phi_hp_r=-12, theta_sh_l=30, theta_sh_r=20, phi_sh_l=-40,
                             phi_sh_r=-35, theta_el_l=20, theta_el_r=30),
    "fallen_sideways": _pose(theta_bd=10, phi_bd=70, theta_hp_l=30, theta_hp_r=10, theta_kn_l=40, theta_kn_r=20,
                             theta_sh_l=30, theta_sh_r=100, theta_el_l=30, theta_el_r=20, phi_sh_r=-20),
    "hands_knees": _pose(theta_bd=85, theta_hp_l=85, theta_hp_r=90, theta_kn_l=90, theta_kn_r=85,
                         theta_sh_l=85, theta_sh_r=90, theta_el_l=5, theta_el_r=5, phi_hp_l=-5, phi_hp_r=-5),
}
FLOOR_POSES = tuple(_FLOOR)
POSES: Mapping[str, Pose] = {**_PAPER, **_FLOOR}


def pose(name: str, psi_bd: float = 30.0) -> Pose:
    """The named pose (PAPER_POSES or FLOOR_POSES) with body yaw ``psi_bd`` degrees (left turn positive)."""
    if name not in POSES:
        raise KeyError(f"unknown pose {name!r}; known: {', '.join(POSES)}")
    return POSES[name].replace(psi_bd=psi_bd)


STANDING = _pose(theta_hp_l=1, theta_hp_r=1, theta_kn_l=2, theta_kn_r=2, phi_hp_l=-3, phi_hp_r=-3,
                 theta_sh_l=3, theta_sh_r=3, phi_sh_l=-6, phi_sh_r=-6, theta_el_l=8, theta_el_r=8)


# --- camera and rendering ------------------------------------------------------------------------------

@dataclass(frozen=True)
class LevelCamera:
    """A level camera looking along +z (image x right, y down), placed relative to the body it renders.
    (bench's other cameras: ``mocap_landmarks.LookAtCamera``, aimed at a point of a mocap world;
    ``falls_body.WorldCamera``, a room camera with a tilt and roll for the fall scenarios.)

    model: "orthographic" (the paper's reprojection) or "pinhole". Orthographic: ``px_per_m`` pixels per
    metre (None: a standing body fills 60 % of the image height, so raised arms and a lying body fit). Pinhole: ``fx, fy, cx, cy`` in pixels
    (cx, cy None: the image centre); the person's feet stand ``distance_m`` in front of the camera.
    height_m: camera height above the floor (None: half the body height for orthographic, 1.0 m for pinhole).
    """

    model: str = "orthographic"
    px_per_m: float | None = None
    fx: float = 600.0
    fy: float = 600.0
    cx: float | None = None
    cy: float | None = None
    distance_m: float = 3.0
    height_m: float | None = None

    def __post_init__(self) -> None:
        if self.model not in ("orthographic", "pinhole"):
            raise ValueError(f"camera model {self.model!r} is not one of: orthographic, pinhole")
        if self.model == "pinhole" and self.distance_m <= 0.5:
            raise ValueError(f"distance_m {self.distance_m} is too close for a whole body (> 0.5 m)")

    def intrinsics(self, image_size: tuple[int, int]) -> Intrinsics:
        """The intrinsics of the pinhole model for this image size."""
        w, h = image_size
        return Intrinsics(self.fx, self.fy, w / 2.0 if self.cx is None else self.cx,
                          h / 2.0 if self.cy is None else self.cy, w, h)


FILL = 0.6  # default orthographic scale: a standing body spans this fraction of the image height


@dataclass(frozen=True)
class Placement:
    """Where a rendered person is: the anchor point's lateral offset and extra depth, metres.

    anchor: "hips" puts the mid-hip there (a static pose in the middle of the image), "feet" the middle of
    the ankles (a motion: a fall turns about the feet, which stay where they were).
    """

    x_m: float = 0.0
    z_m: float = 0.0
    anchor: str = "hips"

    def __post_init__(self) -> None:
        if self.anchor not in ("hips", "feet"):
            raise ValueError(f"anchor {self.anchor!r} is not one of: hips, feet")


def _world_points(pose_: Pose, dims: BodyDimensions, placement: Placement, depth: float, floor_y: float):
    """Camera-axes world points (33, 3): the lowest landmark on the floor, the anchor at the placement."""
    pts = landmarks_camera(pose_, dims)
    ref = 0.5 * (pts[27] + pts[28]) if placement.anchor == "feet" else np.zeros(3)
    root = np.array([placement.x_m - ref[0], floor_y - pts[:, 1].max(), depth + placement.z_m - ref[2]])
    return pts + root, root


def render(
    pose_: Pose,
    *,
    height_m: float = 1.60,
    dims: BodyDimensions | None = None,
    image_size: tuple[int, int] = (640, 480),
    camera: LevelCamera | None = None,
    placement: Placement | None = None,
    noise_px: float = 0.0,
    seed: int | None = None,
    visible_margin_px: float = 0.0,
) -> np.ndarray:
    """The (33, 5) landmarks ``[x_px, y_px, z, visibility, presence]`` of ``pose_`` as a camera sees it.

    x, y: pixels (x right, y down); z: depth relative to the mid-hip on the x pixel scale (negative nearer,
    as MediaPipe); visibility and presence 0.99 inside the image (grown by ``visible_margin_px``) and 0.05
    outside. ``noise_px``: standard deviation of Gaussian noise added to x and y (seeded by ``seed``).
    """
    dims = dims or BodyDimensions.from_height(height_m)
    camera = camera or LevelCamera()
    placement = placement or Placement()
    w, h = image_size
    if camera.model == "orthographic":
        cam_h = 0.5 * dims.body_height_m if camera.height_m is None else camera.height_m
        s = camera.px_per_m or FILL * h / dims.body_height_m
        pts, root = _world_points(pose_, dims, placement, 0.0, cam_h)
        cx, cy = w / 2.0, h / 2.0
        x = cx + s * pts[:, 0]
        y = cy + s * pts[:, 1]
        z = s * (pts[:, 2] - root[2])
    else:
        cam_h = 1.0 if camera.height_m is None else camera.height_m
        k = camera.intrinsics(image_size)
        fx, fy, cx, cy = k.fx, k.fy, k.cx, k.cy
        pts, root = _world_points(pose_, dims, placement, camera.distance_m, cam_h)
        if (pts[:, 2] < 0.05).any():
            raise ValueError("part of the body is behind the camera; increase LevelCamera.distance_m")
        x = cx + fx * pts[:, 0] / pts[:, 2]
        y = cy + fy * pts[:, 1] / pts[:, 2]
        z = fx / root[2] * (pts[:, 2] - root[2])
    if noise_px > 0:
        rng = np.random.default_rng(seed)
        x = x + rng.normal(0.0, noise_px, size=33)
        y = y + rng.normal(0.0, noise_px, size=33)
    m = visible_margin_px
    inside = (x >= -m) & (x < w + m) & (y >= -m) & (y < h + m)
    vis = np.where(inside, 0.99, 0.05)
    return np.column_stack([x, y, z, vis, vis])


def apparent_gamma(dims: BodyDimensions, image_size: tuple[int, int], camera: LevelCamera | None = None,
                   placement: Placement | None = None) -> float:
    """The size factor gamma the fit reports for this camera: standing body height in pixels / image height.

    (Orthographic: exact. Pinhole: at the depth of the mid-hip of a standing person.)
    """
    camera = camera or LevelCamera()
    h = image_size[1]
    if camera.model == "orthographic":
        s = camera.px_per_m or FILL * h / dims.body_height_m
    else:
        placement = placement or Placement()
        s = camera.fy / (camera.distance_m + placement.z_m)
    return s * dims.body_height_m / h


def ground_truth(pose_: Pose, dims: BodyDimensions, gamma: float = 1.0, seq: int = 0, t: float = 0.0) -> FitResult:
    """The FitResult a perfect fit of ``pose_`` would give (joints_3d in camera axes, metres, mid-hip origin)."""
    return FitResult(seq=seq, t=t, ok=True, loss=0.0, variables=pose_.variables(gamma),
                     joint_angles_deg=dict(pose_.joints), joints_3d=joints_3d(pose_, dims))


# --- motion sequences ----------------------------------------------------------------------------------

def _lerp_pose(a: Pose, b: Pose, u: float) -> Pose:
    joints = {k: (1 - u) * a.joints[k] + u * b.joints[k] for k in a.joints}
    return Pose(joints, theta_bd=(1 - u) * a.theta_bd + u * b.theta_bd,
                phi_bd=(1 - u) * a.phi_bd + u * b.phi_bd, psi_bd=(1 - u) * a.psi_bd + u * b.psi_bd)


def _smooth(u: float) -> float:
    return u * u * (3 - 2 * u)


def _accelerate(u: float) -> float:
    """Toppling: starts slowly, hits the floor fast (angle ~ t^2)."""
    return u * u


@dataclass(frozen=True)
class Sequence:
    """A motion with ground truth. ``pose_at(t)`` for 0 <= t <= duration_s (clamped outside).

    is_fall: the motion ends on the floor uncontrolled; impact_s: time the body hits the floor (falls only);
    on_floor_from_s: from this time on the person lies or sits on the floor (None if never).
    """

    name: str
    duration_s: float
    keyframes: tuple[tuple[float, Pose, str], ...]   # (time, pose, easing into this keyframe)
    is_fall: bool = False
    impact_s: float | None = None
    on_floor_from_s: float | None = None
    description: str = ""

    def pose_at(self, t: float) -> Pose:
        t = min(max(float(t), 0.0), self.duration_s)
        frames = self.keyframes
        if t <= frames[0][0]:
            return frames[0][1]
        for (t0, p0, _), (t1, p1, ease) in zip(frames, frames[1:], strict=False):
            if t <= t1:
                u = 0.0 if t1 <= t0 else (t - t0) / (t1 - t0)
                return _lerp_pose(p0, p1, (_accelerate if ease == "accelerate" else _smooth)(u))
        return frames[-1][1]


def _seq(name: str, duration: float, frames: list[tuple[float, Pose, str]], psi: float, **kw) -> Sequence:
    frames = tuple((t, p.replace(psi_bd=p.psi_bd + psi), e) for t, p, e in frames)
    return Sequence(name, duration, frames, **kw)


def _sequences(psi: float) -> dict[str, Callable[[], Sequence]]:
    stand = STANDING
    sit = _PAPER["sit_chair"]
    squat = _pose(theta_tr=35, theta_hp_l=105, theta_hp_r=105, theta_kn_l=115, theta_kn_r=115,
                  phi_hp_l=-12, phi_hp_r=-12, theta_sh_l=80, theta_sh_r=80, theta_el_l=10, theta_el_r=10)
    stumble = _pose(theta_bd=8, theta_hp_l=15, theta_hp_r=5, theta_kn_l=20, theta_kn_r=10, theta_sh_l=40,
                    theta_sh_r=45, theta_el_l=20, theta_el_r=20)
    prone = _FLOOR["fallen_forward"]
    back_sit = _pose(theta_bd=-10, theta_hp_l=60, theta_hp_r=55, theta_kn_l=70, theta_kn_r=65, theta_sh_l=40,
                     theta_sh_r=35, theta_el_l=20, theta_el_r=20)
    supine = _FLOOR["fallen_backward"]
    side_buckle = _pose(phi_bd=10, theta_hp_l=20, theta_kn_l=35, theta_hp_r=10, theta_kn_r=15, theta_sh_r=40,
                        phi_sh_r=-30)
    side = _FLOOR["fallen_sideways"]
    kneel2 = _pose(theta_hp_l=0, theta_hp_r=0, theta_kn_l=90, theta_kn_r=90, theta_sh_l=10, theta_sh_r=10)
    fours = _FLOOR["hands_knees"]
    lying_front = _FLOOR["lying_front"].replace(theta_sh_l=20, theta_el_l=20)
    floor_sit = _FLOOR["sitting_floor_knees_up"]
    return {
        "stand_still": lambda: _seq("stand_still", 3.0, [(0.0, stand, "smooth"), (3.0, stand, "smooth")], psi,
                                    description="standing quietly"),
        "stand_to_sit": lambda: _seq("stand_to_sit", 4.0, [(0.0, stand, "smooth"), (1.0, stand, "smooth"),
                                                           (2.5, sit, "smooth"), (4.0, sit, "smooth")], psi,
                                     description="sit down on a chair (not a fall)"),
        "sit_to_stand": lambda: _seq("sit_to_stand", 4.0, [(0.0, sit, "smooth"), (1.0, sit, "smooth"),
                                                           (2.5, stand, "smooth"), (4.0, stand, "smooth")], psi,
                                     description="stand up from a chair"),
        "squat": lambda: _seq("squat", 4.0, [(0.0, stand, "smooth"), (0.5, stand, "smooth"), (2.0, squat, "smooth"),
                                             (3.5, stand, "smooth"), (4.0, stand, "smooth")], psi,
                              description="squat down and up (not a fall)"),
        "fall_forward": lambda: _seq("fall_forward", 4.0, [(0.0, stand, "smooth"), (1.0, stand, "smooth"),
                                                           (1.25, stumble, "smooth"), (2.0, prone, "accelerate"),
                                                           (4.0, prone, "smooth")], psi,
                                     is_fall=True, impact_s=2.0, on_floor_from_s=2.0,
                                     description="trip and fall forward, then lie still"),
        "fall_backward": lambda: _seq("fall_backward", 4.0, [(0.0, stand, "smooth"), (1.0, stand, "smooth"),
                                                             (1.4, back_sit, "smooth"), (1.9, supine, "accelerate"),
                                                             (4.0, supine, "smooth")], psi,
                                      is_fall=True, impact_s=1.9, on_floor_from_s=1.9,
                                      description="lose balance backwards, sit back and fall on the back"),
        "fall_sideways": lambda: _seq("fall_sideways", 4.0, [(0.0, stand, "smooth"), (1.0, stand, "smooth"),
                                                             (1.3, side_buckle, "smooth"), (2.0, side, "accelerate"),
                                                             (4.0, side, "smooth")], psi,
                                      is_fall=True, impact_s=2.0, on_floor_from_s=2.0,
                                      description="knees buckle, fall on the left side"),
        "lie_down_slowly": lambda: _seq("lie_down_slowly", 8.0, [(0.0, stand, "smooth"), (0.5, stand, "smooth"),
                                                                 (2.5, kneel2, "smooth"), (4.5, fours, "smooth"),
                                                                 (6.5, lying_front, "smooth"),
                                                                 (8.0, lying_front, "smooth")], psi,
                                        on_floor_from_s=6.5,
                                        description="kneel, go on all fours, lie down on the front (controlled)"),
        "sit_on_floor": lambda: _seq("sit_on_floor", 6.0, [(0.0, stand, "smooth"), (0.5, stand, "smooth"),
                                                           (2.5, squat, "smooth"), (4.0, floor_sit, "smooth"),
                                                           (6.0, floor_sit, "smooth")], psi,
                                     on_floor_from_s=4.0, description="squat and sit down on the floor (controlled)"),
    }


SEQUENCE_NAMES = tuple(_sequences(0.0))


def sequence(name: str, psi_bd: float = 30.0) -> Sequence:
    """The named motion with body yaw ``psi_bd`` degrees added to every keyframe."""
    table = _sequences(psi_bd)
    if name not in table:
        raise KeyError(f"unknown sequence {name!r}; known: {', '.join(table)}")
    return table[name]()


def render_sequence(seq: Sequence, fps: float = 30.0, *, seed: int | None = None, **render_kwargs
                    ) -> list[tuple[float, np.ndarray, Pose]]:
    """Frames ``(t, landmarks (33, 5), true pose)`` at ``fps``; noise is seeded per frame from ``seed``.

    The feet stay where they are (``Placement(anchor="feet")``) unless a placement is given.
    """
    render_kwargs.setdefault("placement", Placement(anchor="feet"))
    n = int(math.floor(seq.duration_s * fps + 1e-9)) + 1
    out = []
    for i in range(n):
        t = i / fps
        p = seq.pose_at(t)
        frame_seed = None if seed is None else seed * 100003 + i
        out.append((t, render(p, seed=frame_seed, **render_kwargs), p))
    return out
