"""Scripted fall and daily-activity scenarios: keyframed motions of ``bench.falls_body``, rendered through a
pinhole camera to 33x5 landmarks at a fixed frame rate, with ground-truth onset and impact times.

A motion is a list of ``Key`` (time, pose, seat under the trunk, easing of the segment that ends at the key).
Falls use ease-in (the body accelerates until the impact, as an inverted pendulum does), daily activities
ease in and out (controlled movement). With ``anchor="feet"`` the feet stay where they were at the start of
the segment (the body topples over them); otherwise the pelvis moves to the key's ``xy``.

``catalogue(split)`` builds the benchmark's scenarios: ``"tune"`` (the set the thresholds were chosen on) and
``"heldout"`` (other speeds, views, distances and noise seeds; never used for tuning).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, field, replace

import numpy as np

from posed.bench.falls_body import Body, RestingPlace, StickPose, WorldCamera, place
from posed.fitting import FitResult

STAND = StickPose()
SIT = StickPose(hip_flex_l=90, hip_flex_r=90, knee_l=90, knee_r=90, sh_flex_l=30, sh_flex_r=30, elbow_l=60,
                elbow_r=60)


@dataclass(frozen=True)
class Key:
    t: float
    pose: StickPose
    seat: float | None = None
    ease: str = "smooth"            # smooth (in-out), fall (accelerating), linear, hold
    anchor: str = "pelvis"          # pelvis: move to xy; feet: keep the feet where they were
    xy: tuple[float, float] | None = None
    lift: float = 0.0


def _ease(kind: str, w: float) -> float:
    if kind == "linear":
        return w
    if kind == "fall":
        return w ** 2.2
    if kind == "hold":
        return 0.0 if w < 1 else 1.0
    return 0.5 - 0.5 * math.cos(math.pi * w)


@dataclass(frozen=True)
class Truth:
    """What happened: for a fall the onset and impact (capture seconds); None for daily activities."""

    kind: str                        # "fall" or "adl"
    t_onset: float | None = None
    t_impact: float | None = None
    seen_falling: bool = True        # False: the person is found lying


@dataclass
class Scenario:
    name: str
    kind: str
    keys: list[Key]
    truth: Truth
    camera: WorldCamera
    body: Body = field(default_factory=Body)
    fps: float = 10.0
    noise_frac: float = 0.01
    seed: int = 0
    dropouts: tuple[tuple[float, float], ...] = ()   # capture-time intervals with no landmarks
    start_xy: tuple[float, float] = (0.0, 3.0)

    @property
    def duration(self) -> float:
        return self.keys[-1].t


@dataclass(frozen=True)
class Frame:
    seq: int
    t: float
    landmarks: np.ndarray | None
    joints_world: dict[str, np.ndarray]


def _pose_at(keys: list[Key], t: float) -> tuple[int, float]:
    """Index of the segment (keys[i-1] -> keys[i]) holding t, and the eased weight."""
    if t <= keys[0].t:
        return 0, 1.0
    for i in range(1, len(keys)):
        if t <= keys[i].t:
            span = keys[i].t - keys[i - 1].t
            w = 1.0 if span <= 0 else (t - keys[i - 1].t) / span
            return i, _ease(keys[i].ease, w)
    return len(keys) - 1, 1.0


def _seat(a: float | None, b: float | None, w: float) -> float | None:
    if a is None and b is None:
        return None
    return (a if a is not None else 0.0) * (1 - w) + (b if b is not None else 0.0) * w


def frames(sc: Scenario) -> Iterator[Frame]:
    """Render the scenario frame by frame (deterministic for a given seed)."""
    rng = np.random.default_rng(sc.seed)
    keys = sc.keys
    n = int(math.floor(sc.duration * sc.fps + 1e-9)) + 1
    xy = np.array(sc.start_xy, float)
    seg_start_xy = xy.copy()
    seg_feet: np.ndarray | None = None
    current_seg = -1
    for k in range(n):
        t = k / sc.fps
        i, w = _pose_at(keys, t)
        if i != current_seg:  # entering a new segment: remember where the pelvis and feet are
            current_seg = i
            seg_start_xy = xy.copy()
            seg_feet = None
        a, b = keys[max(i - 1, 0)], keys[i]
        pose = a.pose.lerp(b.pose, w)
        seat = _seat(a.seat, b.seat, w)
        lift = a.lift * (1 - w) + b.lift * w
        if b.anchor == "feet":
            probe = place(pose, sc.body, RestingPlace(0.0, 0.0, seat, lift))
            feet = 0.5 * (probe["left_ankle"][:2] + probe["right_ankle"][:2])
            if seg_feet is None:
                start = place(a.pose, sc.body, RestingPlace(0.0, 0.0, a.seat, a.lift))
                seg_feet = seg_start_xy + 0.5 * (start["left_ankle"][:2] + start["right_ankle"][:2])
            xy = seg_feet - feet
        elif b.xy is not None:
            src = np.array(a.xy, float) if a.xy is not None else seg_start_xy
            xy = src * (1 - w) + np.array(b.xy, float) * w
        joints = place(pose, sc.body, RestingPlace(float(xy[0]), float(xy[1]), seat, lift))
        lost = any(lo <= t < hi for lo, hi in sc.dropouts)
        lm = None if lost else sc.camera.project(joints, sc.body, rng, sc.noise_frac)
        yield Frame(k, t, lm, joints)


def truth_result(frame: Frame, camera: WorldCamera) -> FitResult:
    """A perfect fit of the frame (joints in camera axes, origin mid-hip) for tests of the detector alone."""
    if frame.landmarks is None:
        return FitResult.failure(frame.seq, frame.t, "no person")
    j = frame.joints_world
    angles = {"theta_hp_l": 0.0, "theta_hp_r": 0.0, "theta_kn_l": 0.0, "theta_kn_r": 0.0}
    for side in ("left", "right"):
        s = side[0]
        pelvis_up = 0.5 * (j["left_shoulder"] + j["right_shoulder"]) - 0.5 * (j["left_hip"] + j["right_hip"])
        thigh = j[f"{side}_knee"] - j[f"{side}_hip"]
        shank = j[f"{side}_ankle"] - j[f"{side}_knee"]
        angles[f"theta_hp_{s}"] = 180.0 - _angle(pelvis_up, thigh)
        angles[f"theta_kn_{s}"] = _angle(thigh, shank)
    return FitResult(seq=frame.seq, t=frame.t, ok=True, loss=0.0, joint_angles_deg=angles,
                     joints_3d=camera.joints_camera(j))


def _angle(a: np.ndarray, b: np.ndarray) -> float:
    c = float(a @ b) / max(float(np.linalg.norm(a) * np.linalg.norm(b)), 1e-12)
    return math.degrees(math.acos(max(-1.0, min(1.0, c))))


# ---------------------------------------------------------------------------- motions
# Each returns (keys, truth). ``s`` scales the duration of the movement itself; ``side`` is +1/-1.


def _lie(direction: str, side: float = 1.0) -> StickPose:
    """The pose a fall ends in: prone (forward), supine (backward) or on the side."""
    if direction == "forward":
        return StickPose(pitch=88, hip_flex_l=0, hip_flex_r=-5, knee_l=15, knee_r=5, sh_flex_l=172, sh_flex_r=168,
                         elbow_l=0, elbow_r=0, head_flex=-25, ankle=60)
    if direction == "backward":
        return StickPose(pitch=-86, hip_flex_l=20, hip_flex_r=10, knee_l=30, knee_r=15, sh_abd_l=70, sh_abd_r=60,
                         elbow_l=20, elbow_r=20, head_flex=20, ankle=30)
    return StickPose(roll=86 * side, hip_flex_l=25, hip_flex_r=35, knee_l=40, knee_r=50, sh_flex_l=100, sh_flex_r=100,
                     sh_abd_l=0, sh_abd_r=0, elbow_l=50, elbow_r=60, ankle=30)


def fall_from_standing(direction: str, s: float, side: float = 1.0, lead_in: float = 2.0,
                       after: float = 3.0) -> tuple[list[Key], Truth]:
    t0 = lead_in
    stumble = StickPose(trunk_flex=10 if direction == "forward" else -5, sh_flex_l=40, sh_flex_r=40, knee_l=10,
                        knee_r=5, roll=8 * side if direction == "sideways" else 0.0)
    d_fall = 0.75 * s
    keys = [Key(0.0, STAND), Key(t0, STAND, ease="hold"), Key(t0 + 0.25 * s, stumble),
            Key(t0 + 0.25 * s + d_fall, _lie(direction, side), ease="fall", anchor="feet"),
            Key(t0 + 0.25 * s + d_fall + after, _lie(direction, side).with_(knee_l=25), ease="smooth")]
    return keys, Truth("fall", t_onset=t0, t_impact=t0 + 0.25 * s + d_fall)


def fall_backward_via_sitting(s: float, lead_in: float = 2.0, after: float = 3.0) -> tuple[list[Key], Truth]:
    """Backward fall that lands on the buttocks first, then the back."""
    t0 = lead_in
    seated = StickPose(pitch=-15, hip_flex_l=80, hip_flex_r=75, knee_l=60, knee_r=50, sh_abd_l=40, sh_abd_r=40,
                       sh_flex_l=30, sh_flex_r=30)
    keys = [Key(0.0, STAND), Key(t0, STAND, ease="hold"),
            Key(t0 + 0.55 * s, seated, ease="fall", anchor="feet"),
            Key(t0 + 0.55 * s + 0.45 * s, _lie("backward"), ease="fall"),
            Key(t0 + 1.0 * s + after, _lie("backward"), ease="smooth")]
    return keys, Truth("fall", t_onset=t0, t_impact=t0 + 0.55 * s)


def fall_from_sitting(direction: str, s: float, side: float = 1.0, lead_in: float = 2.0,
                      after: float = 3.0, seat: float = 0.46) -> tuple[list[Key], Truth]:
    """Sitting on a chair, then sliding or toppling off it to the floor (the chair's seat drops away)."""
    t0 = lead_in
    if direction == "forward":  # slides onto the knees, then pitches forward onto the floor
        end = _lie("forward").with_(hip_flex_l=10, knee_l=40)
        knees = StickPose(pitch=30, hip_flex_l=60, hip_flex_r=55, knee_l=110, knee_r=100, trunk_flex=15,
                          sh_flex_l=70, sh_flex_r=70)
    elif direction == "backward":  # slides off the front of the seat onto the back
        end = _lie("backward").with_(hip_flex_l=50, hip_flex_r=40, knee_l=70, knee_r=60)
        knees = None
    else:
        end = _lie("sideways", side)
        knees = None
    lean = SIT.with_(trunk_flex=25 if direction == "forward" else 0.0,
                     roll=12 * side if direction == "sideways" else 0.0,
                     pitch=-10 if direction == "backward" else 0.0)
    d = 0.7 * s
    keys = [Key(0.0, SIT, seat=seat), Key(t0, SIT, seat=seat, ease="hold"), Key(t0 + 0.3 * s, lean, seat=seat)]
    if knees is not None:
        keys.append(Key(t0 + 0.3 * s + 0.45 * d, knees, seat=None, ease="fall"))
    keys += [Key(t0 + 0.3 * s + d, end, seat=None, ease="fall"),
             Key(t0 + 0.3 * s + d + after, end.with_(knee_l=end.knee_l + 10), ease="smooth")]
    return keys, Truth("fall", t_onset=t0 + 0.3 * s, t_impact=t0 + 0.3 * s + d)


def collapse(s: float, side: float = 1.0, lead_in: float = 2.0, after: float = 3.0) -> tuple[list[Key], Truth]:
    """A slow fall: the knees give way, the person sinks to the floor and tips over onto the side."""
    t0 = lead_in
    crouch = StickPose(pitch=15, trunk_flex=15, hip_flex_l=75, hip_flex_r=70, knee_l=110, knee_r=100, sh_flex_l=30,
                       sh_flex_r=20)
    floor_sit = StickPose(pitch=-10, hip_flex_l=75, hip_flex_r=70, knee_l=70, knee_r=60, sh_abd_l=30, sh_abd_r=30)
    end = _lie("sideways", side)
    keys = [Key(0.0, STAND), Key(t0, STAND, ease="hold"), Key(t0 + 1.2 * s, crouch, anchor="feet"),
            Key(t0 + 2.0 * s, floor_sit, ease="smooth"),
            Key(t0 + 3.0 * s, end, ease="smooth"), Key(t0 + 3.0 * s + after, end, ease="hold")]
    return keys, Truth("fall", t_onset=t0, t_impact=t0 + 3.0 * s)


def found_lying(direction: str, side: float = 1.0, duration: float = 5.0) -> tuple[list[Key], Truth]:
    """A person already on the floor when the camera first sees them (small movements)."""
    lie = _lie(direction, side)
    keys = [Key(0.0, lie), Key(duration / 2, lie.with_(knee_l=lie.knee_l + 15, sh_flex_r=lie.sh_flex_r + 10)),
            Key(duration, lie)]
    return keys, Truth("fall", t_onset=None, t_impact=0.0, seen_falling=False)


def sit_down(s: float, seat: float = 0.46, hold: float = 3.0) -> tuple[list[Key], Truth]:
    lean = SIT.with_(trunk_flex=30, pitch=10, hip_flex_l=60, hip_flex_r=60, knee_l=60, knee_r=60)
    keys = [Key(0.0, STAND), Key(1.5, STAND, ease="hold"), Key(1.5 + 0.6 * s, lean, seat=seat * 1.3),
            Key(1.5 + 1.2 * s, SIT, seat=seat), Key(1.5 + 1.2 * s + hold, SIT, seat=seat, ease="hold"),
            Key(1.5 + 1.2 * s + hold + 0.6 * s, lean, seat=seat * 1.3),
            Key(1.5 + 2.4 * s + hold, STAND), Key(2.5 + 2.4 * s + hold, STAND, ease="hold")]
    return keys, Truth("adl")


def plop_on_sofa(s: float, seat: float = 0.40) -> tuple[list[Key], Truth]:
    """Dropping fast onto a low sofa and leaning back."""
    slump = SIT.with_(pitch=-20, hip_flex_l=100, hip_flex_r=100, knee_l=80, knee_r=80, sh_abd_l=30,
                      sh_abd_r=30)
    keys = [Key(0.0, STAND), Key(1.5, STAND, ease="hold"), Key(1.5 + 0.45 * s, SIT, seat=seat, ease="fall"),
            Key(2.0 + 0.45 * s, slump, seat=seat), Key(5.0 + 0.45 * s, slump, seat=seat, ease="hold")]
    return keys, Truth("adl")


def bend_pick_up(s: float) -> tuple[list[Key], Truth]:
    bend = StickPose(pitch=35, trunk_flex=50, hip_flex_l=35, hip_flex_r=35, knee_l=15, knee_r=15, sh_flex_l=80,
                     sh_flex_r=75, head_flex=-20)
    keys = [Key(0.0, STAND), Key(1.5, STAND, ease="hold"), Key(1.5 + 1.0 * s, bend, anchor="feet"),
            Key(2.5 + 1.0 * s, bend, ease="hold"), Key(2.5 + 2.0 * s, STAND, anchor="feet"),
            Key(4.0 + 2.0 * s, STAND, ease="hold")]
    return keys, Truth("adl")


def squat(s: float, hold: float = 2.0) -> tuple[list[Key], Truth]:
    deep = StickPose(pitch=25, trunk_flex=15, hip_flex_l=120, hip_flex_r=120, knee_l=140, knee_r=140, sh_flex_l=80,
                     sh_flex_r=80)
    keys = [Key(0.0, STAND), Key(1.5, STAND, ease="hold"), Key(1.5 + 1.2 * s, deep, anchor="feet"),
            Key(1.5 + 1.2 * s + hold, deep, ease="hold"), Key(1.5 + 2.4 * s + hold, STAND, anchor="feet"),
            Key(2.5 + 2.4 * s + hold, STAND, ease="hold")]
    return keys, Truth("adl")


def kneel(s: float, both: bool = True, hold: float = 3.0) -> tuple[list[Key], Truth]:
    if both:
        down = StickPose(knee_l=90, knee_r=90, hip_flex_l=5, hip_flex_r=5, trunk_flex=10, sh_flex_l=20, sh_flex_r=20)
        mid = StickPose(hip_flex_l=90, hip_flex_r=10, knee_l=90, knee_r=80, trunk_flex=10)
    else:
        down = StickPose(hip_flex_l=85, knee_l=90, hip_flex_r=0, knee_r=90, trunk_flex=10, sh_flex_l=20)
        mid = StickPose(hip_flex_l=60, knee_l=70, knee_r=60, hip_flex_r=10, trunk_flex=20)
    keys = [Key(0.0, STAND), Key(1.5, STAND, ease="hold"), Key(1.5 + 0.8 * s, mid, anchor="feet"),
            Key(1.5 + 1.6 * s, down), Key(1.5 + 1.6 * s + hold, down, ease="hold"),
            Key(1.5 + 2.4 * s + hold, mid), Key(1.5 + 3.2 * s + hold, STAND, anchor="feet"),
            Key(2.5 + 3.2 * s + hold, STAND, ease="hold")]
    return keys, Truth("adl")


def lie_on_bed(s: float, bed: float = 0.50, supine: bool = False, side: float = 1.0) -> tuple[list[Key], Truth]:
    sit_edge = SIT.with_(sh_flex_l=10, sh_flex_r=10)
    lie = (StickPose(pitch=-85, hip_flex_l=10, hip_flex_r=5, knee_l=15, knee_r=10, sh_abd_l=20, sh_abd_r=20)
           if supine else StickPose(roll=85 * side, hip_flex_l=30, hip_flex_r=35, knee_l=40, knee_r=45, sh_flex_l=90,
                                    sh_flex_r=80, sh_abd_l=0, sh_abd_r=0, elbow_l=70, elbow_r=60))
    keys = [Key(0.0, STAND), Key(1.5, STAND, ease="hold"), Key(1.5 + 1.5 * s, sit_edge, seat=bed),
            Key(2.5 + 1.5 * s, sit_edge, seat=bed, ease="hold"), Key(2.5 + 3.5 * s, lie, seat=bed),
            Key(6.5 + 3.5 * s, lie, seat=bed, ease="hold")]
    return keys, Truth("adl")


def exercise(kind: str, s: float, reps: int = 3) -> tuple[list[Key], Truth]:
    keys = [Key(0.0, STAND), Key(1.0, STAND, ease="hold")]
    t = 1.0
    if kind == "squats":
        low = StickPose(pitch=20, trunk_flex=10, hip_flex_l=95, hip_flex_r=95, knee_l=100, knee_r=100, sh_flex_l=90,
                        sh_flex_r=90, elbow_l=0, elbow_r=0)
        for _ in range(reps):
            keys += [Key(t + 0.8 * s, low, anchor="feet"), Key(t + 1.6 * s, STAND, anchor="feet")]
            t += 1.6 * s
    elif kind == "jumping_jacks":
        wide = StickPose(hip_abd_l=18, hip_abd_r=18, sh_abd_l=160, sh_abd_r=160, elbow_l=10, elbow_r=10)
        for _ in range(reps * 2):
            keys += [Key(t + 0.25 * s, wide.with_(knee_l=10, knee_r=10), lift=0.10, ease="smooth"),
                     Key(t + 0.5 * s, wide), Key(t + 0.75 * s, STAND.with_(knee_l=10, knee_r=10), lift=0.10),
                     Key(t + 1.0 * s, STAND)]
            t += 1.0 * s
    elif kind == "toe_touches":
        down = StickPose(pitch=45, trunk_flex=45, hip_flex_l=45, hip_flex_r=45, sh_flex_l=90, sh_flex_r=90,
                         head_flex=-10)
        for _ in range(reps):
            keys += [Key(t + 1.0 * s, down, anchor="feet"), Key(t + 2.0 * s, STAND, anchor="feet")]
            t += 2.0 * s
    elif kind == "lunges":
        for i in range(reps):
            sgn = 1 if i % 2 == 0 else -1
            lunge = StickPose(hip_flex_l=85 if sgn > 0 else -10, hip_flex_r=85 if sgn < 0 else -10,
                              knee_l=90 if sgn > 0 else 95, knee_r=90 if sgn < 0 else 95, trunk_flex=5)
            keys += [Key(t + 0.9 * s, lunge), Key(t + 1.8 * s, STAND)]
            t += 1.8 * s
    else:
        raise ValueError(f"unknown exercise {kind!r}")
    keys.append(Key(t + 1.0, STAND, ease="hold"))
    return keys, Truth("adl")


def walk(path: list[tuple[float, float]], speed: float = 1.1, start_pause: float = 0.5) -> tuple[list[Key], Truth]:
    """Walk through the ground points (x, y) at ``speed`` m/s with a simple gait (hips, knees, arms)."""
    keys = [Key(0.0, STAND, xy=path[0]), Key(start_pause, STAND, xy=path[0], ease="hold")]
    t = start_pause
    step = 0.3  # half a stride, s
    phase = 0
    for a, b in zip(path[:-1], path[1:], strict=True):
        a_, b_ = np.array(a, float), np.array(b, float)
        dist = float(np.linalg.norm(b_ - a_))
        yaw = math.degrees(math.atan2(-(b_ - a_)[0], (b_ - a_)[1]))
        n = max(1, int(round(dist / (speed * step))))
        for k in range(1, n + 1):
            sgn = 1 if phase % 2 == 0 else -1
            phase += 1
            pose = StickPose(yaw=yaw, hip_flex_l=20 * sgn, hip_flex_r=-20 * sgn, knee_l=10 + (25 if sgn < 0 else 0),
                             knee_r=10 + (25 if sgn > 0 else 0), sh_flex_l=-15 * sgn, sh_flex_r=15 * sgn)
            p = a_ + (b_ - a_) * k / n
            keys.append(Key(t + step, pose, xy=(float(p[0]), float(p[1])), ease="linear"))
            t += step
    keys.append(Key(t + 0.4, STAND.with_(yaw=keys[-1].pose.yaw), xy=keys[-1].xy))
    return keys, Truth("adl")


# ---------------------------------------------------------------------------- the catalogue


def make(name: str, kind: str, motion: tuple[list[Key], Truth], view: float, distance: float, cam_height: float,
         tilt: float, seed: int, facing_offset: float = 0.0, fps: float = 10.0,
         dropouts=(), start_xy=None, noise_frac: float = 0.01, image: tuple[int, int, float] = (640, 480, 69.0)
         ) -> Scenario:
    """Place the person ``distance`` m in front of a camera; ``view`` is the direction the camera sees the
    person from, in degrees around them (0: the person faces the camera, 90: their left side, 180: back)."""
    keys, truth = motion
    facing = 180.0 + view + facing_offset
    keys = [replace(k, pose=k.pose.with_(yaw=k.pose.yaw + facing)) for k in keys]
    if start_xy is None:
        start_xy = (0.0, distance)
    return Scenario(name=name, kind=kind, keys=keys, truth=truth,
                    camera=WorldCamera(z=cam_height, tilt=tilt, width=image[0], height=image[1], hfov=image[2]),
                    fps=fps, seed=seed, dropouts=tuple(dropouts),
                    start_xy=start_xy, noise_frac=noise_frac)


@dataclass(frozen=True)
class SplitSpec:
    speeds: dict[str, float]
    views: tuple[float, ...]
    distances: tuple[float, ...]
    cams: tuple[tuple[float, float], ...]   # (height, tilt)
    seed0: int
    adl_speeds: dict[str, float]
    image: tuple[int, int, float] = (640, 480, 69.0)   # width, height (px), horizontal field of view (deg)


SPLITS = {
    "tune": SplitSpec(speeds={"fast": 1.0, "slow": 2.5}, views=(30.0, 100.0), distances=(3.0, 3.8),
                      cams=((1.0, 12.0), (1.2, 18.0)), seed0=1000, adl_speeds={"normal": 1.0, "quick": 0.6}),
    "heldout": SplitSpec(speeds={"fast": 0.8, "medium": 1.6, "slow": 3.2}, views=(150.0, 250.0, 60.0),
                         distances=(2.6, 4.4), cams=((0.9, 8.0), (1.3, 22.0)), seed0=5000,
                         adl_speeds={"normal": 1.3, "quick": 0.5}),
}


# Other mounts: the same motions seen by another camera (``catalogue(split, mount)``). "wall": a camera high on
# a room's wall tilted down, 320x240 (the low-resolution home and office recordings of public fall datasets),
# its field of view (62 deg) not the detector's default (69); people stand 1.7-2.4 m from the wall so that the
# whole body is in view (at 2 m height and 35 deg the image covers 6-64 deg below the horizon). "corner": a
# second wall camera, never used to choose or check a rule while building (a held-out mount): higher, less
# tilted and wider than the detector's assumed lens (2.4 m, 25 deg, 74 deg across 320x240: the image covers
# -4 to 54 deg below the horizon), the person 3.0-4.2 m away (a fall towards the camera may leave the image).
MOUNTS = {
    "robot": None,
    "wall": {"cams": ((2.0, 35.0),), "distances": (1.7, 2.4), "image": (320, 240, 62.0)},
    "corner": {"cams": ((2.4, 25.0),), "distances": (3.0, 4.2), "image": (320, 240, 74.0)},
}


def catalogue(split: str = "tune", mount: str = "robot") -> list[Scenario]:
    """Every scenario of one split (names are unique and stable), seen from ``mount`` (``MOUNTS``; names of
    another mount than the robot's start with it, e.g. ``wall/heldout/...``)."""
    if split not in SPLITS:
        raise ValueError(f"split {split!r} is not one of: {', '.join(SPLITS)}")
    if mount not in MOUNTS:
        raise ValueError(f"mount {mount!r} is not one of: {', '.join(MOUNTS)}")
    sp = SPLITS[split]
    if MOUNTS[mount] is not None:
        sp = replace(sp, **MOUNTS[mount])
    prefix = "" if mount == "robot" else f"{mount}/"
    out: list[Scenario] = []
    seed = sp.seed0

    def add(name, kind, motion, view, dist, cam, **kw):
        nonlocal seed
        seed += 1
        out.append(make(f"{prefix}{split}/{name}", kind, motion, view, dist, cam[0], cam[1], seed, image=sp.image, **kw))

    cams, dists, views = sp.cams, sp.distances, sp.views
    # falls: direction x origin x speed x view
    for si, (sname, s) in enumerate(sp.speeds.items()):
        for vi, view in enumerate(views):
            cam, dist = cams[(si + vi) % len(cams)], dists[(si + 2 * vi) % len(dists)]
            side = 1.0 if (si + vi) % 2 == 0 else -1.0
            tag = f"{sname}-v{int(view)}"
            for direction in ("forward", "backward", "sideways"):
                add(f"fall/standing-{direction}/{tag}", "fall", fall_from_standing(direction, s, side), view, dist, cam)
                add(f"fall/sitting-{direction}/{tag}", "fall", fall_from_sitting(direction, s, side), view, dist, cam)
            if sname != "fast":
                add(f"fall/collapse/{tag}", "fall", collapse(s / 2.0, side), view, dist, cam)
            else:
                add(f"fall/backward-via-sitting/{tag}", "fall", fall_backward_via_sitting(s), view, dist, cam)
    for vi, view in enumerate(views):
        cam, dist = cams[vi % len(cams)], dists[vi % len(dists)]
        for direction in ("forward", "backward", "sideways"):
            add(f"fall/found-lying-{direction}/v{int(view)}", "fall", found_lying(direction, 1.0 if vi % 2 else -1.0),
                view, dist, cam)
        # lost for a few frames around the impact
        motion = fall_from_standing("sideways", list(sp.speeds.values())[0], 1.0)
        ti = motion[1].t_impact
        add(f"fall/occluded-at-impact/v{int(view)}", "fall", motion, view, dist, cam,
            dropouts=((ti - 0.25, ti + 0.25),))
    # daily activities: each at every ADL speed, alternating views and cameras
    for ai, (aname, s) in enumerate(sp.adl_speeds.items()):
        for vi, view in enumerate(views[:2]):
            cam, dist = cams[(ai + vi) % len(cams)], dists[(ai + vi) % len(dists)]
            tag = f"{aname}-v{int(view)}"
            side = 1.0 if vi % 2 == 0 else -1.0
            add(f"adl/sit-down-chair/{tag}", "adl", sit_down(s), view, dist, cam)
            add(f"adl/plop-on-sofa/{tag}", "adl", plop_on_sofa(s), view, dist, cam)
            add(f"adl/bend-pick-up/{tag}", "adl", bend_pick_up(s), view, dist, cam)
            add(f"adl/squat/{tag}", "adl", squat(s), view, dist, cam)
            add(f"adl/kneel-both/{tag}", "adl", kneel(s, True), view, dist, cam)
            add(f"adl/kneel-one/{tag}", "adl", kneel(s, False), view, dist, cam)
            add(f"adl/lie-on-bed-side/{tag}", "adl", lie_on_bed(s, 0.50, False, side), view, dist, cam)
            add(f"adl/lie-on-sofa-back/{tag}", "adl", lie_on_bed(s, 0.42, True), view, dist, cam)
            for ex in ("squats", "jumping_jacks", "toe_touches", "lunges"):
                add(f"adl/exercise-{ex.replace('_', '-')}/{tag}", "adl", exercise(ex, s), view, dist, cam)
    # walking out of view: across the image, and towards the camera until cut off at the bottom
    for vi, (cam, dist) in enumerate(zip(cams, dists, strict=False)):
        half = dist * math.tan(math.radians(34.5)) + 1.5
        add(f"adl/walk-out-sideways/c{vi}", "adl", walk([(0.0, dist), (half, dist)]), 0.0, dist, cam,
            start_xy=(0.0, dist), facing_offset=-180.0)
        add(f"adl/walk-out-towards/c{vi}", "adl", walk([(0.3, dist + 1.0), (0.3, 0.6)], speed=0.9), 0.0, dist, cam,
            start_xy=(0.3, dist + 1.0), facing_offset=-180.0)
    return out
