"""The fall benchmark with a camera that moves: a robot's head tilting and panning, and its base driving.

``posed bench falls --camera static|follow|nod|follow_pan|drive`` renders the scenarios and CMU clips of
``posed bench falls`` (the same bodies, motions, cameras and noise seeds: :mod:`bench.falls_scenarios`,
:func:`bench.falls.cmu_cases`) through a camera whose tilt (and, for the last two, yaw and floor position)
changes frame by frame, and scores the detector in six arms.

Camera motions (``MOTIONS``): the scene's own camera (height 0.9-1.3 m, 8-22 deg down, 640x480, 69 deg) is
the head's home position, ``base``.

* ``static``: the head stays at ``base``: exactly today's frames (same landmarks, bit for bit).
* ``follow``: the head tilts to keep the person's pelvis (mid-hip) on the image's centre row, as a robot
  following the person does (:class:`FollowHead`): it sees the person's landmarks ``delay_s`` after their
  capture (the frame's processing and the hop to the head's controller), and its tilt servo moves towards the
  last target with a first-order time constant ``tau_s``, never faster than ``max_rate_deg_s``. It starts at
  ``base``; it does not pan, so a person walking sideways still leaves the image.
* ``nod``: a slow scan unrelated to the person, ``base + amplitude * sin(2 pi t / period + phase)``, the
  phase drawn from the scene's name (so falls meet the scan at every phase).
* ``follow_pan`` (:mod:`bench.falls_base_motion`, :class:`~bench.falls_base_motion.PanTiltHead`): the head pans
  *and* tilts to keep the mid-hip on the image's centre, with ``follow``'s delay, servo time constant and tilt
  rate limit, and a pan rate limit of 80 deg/s (the slower of the Sony EVI-D30 / EVI-D100 pan speed tables).
* ``drive`` (:class:`~bench.falls_base_motion.DriveBase`): the robot's base drives on the floor (the camera's
  height constant) to keep 2 m from the person, turning to face them, at most 0.5 m/s and 0.5 / 0.6 m/s^2
  (speeding up / slowing down: a Kobuki base's navigation and driver limits), the head following on it as in
  ``follow_pan``. It starts at rest 2 m from the person. The ``imu`` and ``imu_gyro`` arms feel the base: the
  accelerometer reads gravity plus the base's acceleration, the gyro the base's yaw with the head's pan and
  tilt (:func:`bench.falls_base_motion.base_imu_downs`).

The camera turns about its optical centre: its height stays the scene's (a real head's camera sits some 5 cm
in front of the tilt axis, which moves it by under 2 cm over 20 deg); the base carries it on its turning axis.

Arms (``ARMS``), each with the shipped config otherwise:

* ``default``: the config as it is (tilt 0, height 1 m, a guess checked against the body): a freshly started
  robot told nothing about its camera. The fit is given no gravity.
* ``measured``: the head's home tilt, roll and height configured, ``camera_geometry: measured``: what a careful
  integrator does today. The fit is given that mount's gravity, as the daemon's fitting stage does.
* ``robot``: the default config, and the true per-frame mount given with
  ``FallDetector.set_camera_mount(down, height)`` on every frame (down in camera axes, height above the
  floor); the fit is given the same down. Only when the detector has ``set_camera_mount``.
* ``robot_down``: as ``robot`` without the height (``set_camera_mount(down, None)``): the floor then comes from
  the other sources (the feet of people standing or sitting upright, else the configured height).
* ``imu``: the default config and the gravity of an accelerometer on the head (a RealSense D435i's), as
  ``hal.imu`` filters it (:func:`imu_downs`), through ``FallDetector.set_gravity``: what a robot with such a
  camera gets without telling posed anything, when only the accelerometer is used. Under ``follow_pan`` and
  ``drive`` the accelerometer reads the specific force, gravity and the base's acceleration together.
* ``imu_gyro``: as ``imu`` with the camera's gyroscope too (:func:`imu_gyro_downs`): the head's true angular
  rate at 200 Hz with a BMI055's noise and a constant bias drawn per scene from its datasheet's range, and the
  same noiseless accelerometer, through ``hal.imu.GravityEstimate``'s gyro + accelerometer filter; under
  ``follow_pan`` and ``drive`` the gyro reads the base's yaw, the pan and the tilt together.

Under ``drive`` the still head's comparison (``findings``) mixes two things: the base starts 2 m from the person
while the scene's camera is 2.6-4.4 m away, so the person is also seen larger and nearer the image's edges.
"""

from __future__ import annotations

import math
import statistics
import time
import zlib
from collections.abc import Callable, Iterable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from posed.bench import falls_base_motion as base_motion
from posed.bench.falls import (
    DETECTING_STATES,
    Case,
    LowestPelvis,
    Outcome,
    cached_fit,
    cmu_cases,
    outcome_of,
    real_fitter,
    summarise,
)
from posed.bench.falls_body import Body, WorldCamera
from posed.bench.falls_scenarios import Frame, catalogue, frames, truth_result
from posed.daemon.stages.fit import mount_gravity
from posed.falls.config import FallsConfig
from posed.falls.detector import FallDetector
from posed.falls.features import gravity_from_tilt
from posed.fitting import FitResult

CMU_SEED = 77          # bench.falls.cmu_cases: the noise of its n-th view is drawn from CMU_SEED + n
CMU_NOISE = 0.01
TORSO = (11, 12, 23, 24)
IMU_RATE_HZ = 63.0       # the D435i accelerometer's sample rate (hal/imu.py)
# The D435i's gyro (Bosch BMI055, datasheet BST-BMI055-DS000, typical values; hal/imu.py): its lowest rate,
# 200 Hz; noise density 0.014 deg/s/sqrt(Hz), white up to the Nyquist frequency: 0.14 deg/s per sample at
# 200 Hz; zero-rate offset +-1 deg/s, drawn per scene and axis uniformly in that range and held constant
GYRO_RATE_HZ = 200.0
GYRO_NOISE_DENSITY_DEG_S = 0.014
GYRO_BIAS_DEG_S = 1.0
LATENCY_TARGET_S = 1.0   # the fall benchmark's median latency target (bench.commands.falls.TARGETS)


@dataclass(frozen=True)
class FollowHead:
    """A pan-tilt head following the person's pelvis with its tilt.

    Why these numbers:

    * ``max_rate_deg_s`` 60: the tilt of pan-tilt cameras made for robots and conferencing is capped at 50
      deg/s (Sony EVI-D30, long fitted to research robots) to 125 deg/s (EVI-D100), by their command lists'
      speed tables; a robot's integrator keeps it low for sharp images too: at 60 deg/s a 10 ms indoor
      exposure smears 0.6 deg, 5.6 px of a 640 px, 69 deg image.
    * ``delay_s`` 0.15: the head is driven by the pose of a frame it has seen: posed's capture -> publish
      latency is 11-57 ms at p50-p95 on this VM (docs/benchmarks.md, the pipeline benchmark), plus the hop to
      the robot's head controller and its control period (tens of ms), and a frame comes only every 0.1 s.
    * ``tau_s`` 0.15: a position-controlled servo's response: with the delay, the head reaches 63 % of a step
      0.3 s after the frame that asked for it and 95 % after 0.6 s (the 0.2-0.5 s lag of a following head).
    """

    delay_s: float = 0.15
    tau_s: float = 0.15
    max_rate_deg_s: float = 60.0
    step_s: float = 0.005                 # the servo's integration step (its control loop runs at 200 Hz)
    min_tilt_deg: float = -30.0           # mechanical range of the tilt (deg down)
    max_tilt_deg: float = 60.0

    def meaning(self) -> str:
        return (f"the head tilts to keep the pelvis on the image's centre row: it sees each frame's landmarks "
                f"{self.delay_s:g} s after capture, its servo follows with a {self.tau_s:g} s time constant, at "
                f"most {self.max_rate_deg_s:g} deg/s; it starts at the home tilt")


@dataclass(frozen=True)
class Nod:
    """A slow scan of the room: ``base + amplitude_deg * sin(2 pi t / period_s + phase)``."""

    amplitude_deg: float = 12.0
    period_s: float = 6.0

    def phase(self, name: str) -> float:
        return 2.0 * math.pi * (zlib.crc32(name.encode()) % 1000) / 1000.0

    def meaning(self) -> str:
        peak = 2.0 * math.pi * self.amplitude_deg / self.period_s
        return (f"a scan unrelated to the person: the tilt swings +-{self.amplitude_deg:g} deg about the home tilt "
                f"every {self.period_s:g} s (at most {peak:.1f} deg/s), its phase drawn from the scene's name")


FOLLOW = FollowHead()
NOD = Nod()
MOTIONS = {
    "static": "the head stays at its home tilt (the scene's camera): today's frames",
    "follow": FOLLOW.meaning(),
    "nod": NOD.meaning(),
    "follow_pan": base_motion.PAN.meaning(),
    "drive": base_motion.DRIVE.meaning(),
}
ARMS = {
    "default": "the config as it is (tilt 0, height 1 m: a guess checked against the body): a freshly started "
               "robot told nothing about its camera; the fit is given no gravity",
    "measured": "the head's home tilt and height configured, camera_geometry measured (what a careful "
                "integrator does today); the fit is given that mount's gravity",
    "robot": "the default config, and the true mount of every frame given through "
             "FallDetector.set_camera_mount(down, height); the fit is given the same down",
    "robot_down": "as robot, but the height not given (set_camera_mount(down, None)): the floor comes from the "
                  "other sources (the feet of people standing or sitting upright, else the configured 1 m)",
    "imu": "the default config and a camera accelerometer's gravity on every frame, as hal.imu gives it (the "
           "head's true down sampled at 63 Hz, the D435i's rate, through hal.imu.GravityEstimate's 0.5 s "
           "low-pass), set with FallDetector.set_gravity; the fit is given the same down",
    "imu_gyro": "as imu, with the camera's gyroscope too: the head's true angular rate at 200 Hz with a BMI055's "
                "noise (0.014 deg/s/sqrt(Hz)) and a constant bias drawn per scene within its +-1 deg/s, through "
                "hal.imu.GravityEstimate's gyro + accelerometer filter (0.5 s accelerometer correction)",
}
ROBOT_ARMS = ("robot", "robot_down")


def has_camera_mount() -> bool:
    """Whether the detector takes the robot's per-frame mount (``FallDetector.set_camera_mount``)."""
    return callable(getattr(FallDetector, "set_camera_mount", None))


# ---------------------------------------------------------------------------- the head


class StaticHead:
    def __init__(self, base: WorldCamera) -> None:
        self.base = base

    def camera_at(self, t: float) -> WorldCamera:
        return self.base

    def tilt_at(self, t: float) -> float:
        return self.base.tilt

    def observe(self, t: float, landmarks: np.ndarray | None, camera: WorldCamera, world: dict | None = None) -> None:
        pass


class NodHead:
    def __init__(self, base: WorldCamera, nod: Nod, name: str) -> None:
        self.base, self.nod, self.phi = base, nod, nod.phase(name)

    def tilt_at(self, t: float) -> float:
        return self.base.tilt + self.nod.amplitude_deg * math.sin(2.0 * math.pi * t / self.nod.period_s + self.phi)

    def camera_at(self, t: float) -> WorldCamera:
        return replace(self.base, tilt=self.tilt_at(t))

    def observe(self, t: float, landmarks: np.ndarray | None, camera: WorldCamera, world: dict | None = None) -> None:
        pass


class FollowController:
    """The head of :class:`FollowHead`: ``camera_at(t)`` runs the servo on to capture time ``t`` (times never
    go back) and returns the camera then; ``observe`` gives it a frame's landmarks as seen through ``camera``.
    A frame whose hips are not both in the image leaves the target where it was (the head holds)."""

    def __init__(self, base: WorldCamera, head: FollowHead = FOLLOW) -> None:
        self.base, self.head = base, head
        self.tilt = float(base.tilt)
        self.target = float(base.tilt)
        self.t = 0.0
        self.pending: list[tuple[float, float]] = []      # (time the target reaches the head, target tilt)
        self.max_rate_seen = 0.0                          # |deg/s| of any servo step, for the tests
        self.track_t = [0.0]                              # every servo step's time and tilt (tilt_at)
        self.track_tilt = [self.tilt]

    def target_from(self, landmarks: np.ndarray | None, camera: WorldCamera) -> float | None:
        """The tilt that puts the frame's mid-hip on the image's centre row, or None (hips not both seen)."""
        hips = base_motion.seen_hips(landmarks)
        if hips is None:
            return None
        v = float(hips[:, 1].mean())
        f = camera.intrinsics.fy
        cy = camera.height / 2.0
        return float(np.clip(camera.tilt + math.degrees(math.atan((v - cy) / f)),
                             self.head.min_tilt_deg, self.head.max_tilt_deg))

    def observe(self, t: float, landmarks: np.ndarray | None, camera: WorldCamera, world: dict | None = None) -> None:
        target = self.target_from(landmarks, camera)
        if target is not None:
            self.pending.append((t + self.head.delay_s, target))

    def run_to(self, t: float) -> None:
        if t <= self.t:
            return
        n = max(1, int(math.ceil((t - self.t) / self.head.step_s - 1e-9)))
        dt = (t - self.t) / n
        rate_max = self.head.max_rate_deg_s
        for i in range(1, n + 1):
            now = self.t + i * dt
            while self.pending and self.pending[0][0] <= now + 1e-12:
                self.target = self.pending.pop(0)[1]
            rate = max(-rate_max, min(rate_max, (self.target - self.tilt) / self.head.tau_s))
            self.max_rate_seen = max(self.max_rate_seen, abs(rate))
            self.tilt += rate * dt
            self.track_t.append(now)
            self.track_tilt.append(self.tilt)
        self.t = t

    def tilt_at(self, t: float) -> float:
        """The tilt at time ``t`` of the servo's run so far (its steps, linearly between them)."""
        return float(np.interp(t, self.track_t, self.track_tilt))

    def camera_at(self, t: float) -> WorldCamera:
        self.run_to(t)
        return replace(self.base, tilt=self.tilt)


def head_for(motion: str, base: WorldCamera, name: str, follow: FollowHead = FOLLOW, nod: Nod = NOD):
    if motion == "static":
        return StaticHead(base)
    if motion == "follow":
        return FollowController(base, follow)
    if motion == "nod":
        return NodHead(base, nod, name)
    raise ValueError(f"camera motion {motion!r} is not one of: {', '.join(MOTIONS)}")


# ---------------------------------------------------------------------------- rendering


def render(static_frames: Iterable[Frame], head, body: Body, seed: int, noise_frac: float,
           dropouts: tuple[tuple[float, float], ...] = ()) -> tuple[list[Frame], list[WorldCamera]]:
    """The frames of a scene seen by ``head`` (``camera_at``, ``observe``, which is also given the frame's world
    joints: the driving base's depth reading of the person): each frame's world joints projected
    through that frame's camera, the noise drawn as :func:`bench.falls_scenarios.frames` draws it (one
    generator seeded with ``seed``, nothing drawn for a frame that is dropped or behind the camera), so a head
    that never moves gives exactly the same landmarks."""
    rng = np.random.default_rng(seed)
    out: list[Frame] = []
    cams: list[WorldCamera] = []
    for fr in static_frames:
        cam = head.camera_at(fr.t)
        lost = any(lo <= fr.t < hi for lo, hi in dropouts)
        lm = None if lost else cam.project(fr.joints_world, body, rng, noise_frac)
        head.observe(fr.t, lm, cam, fr.joints_world)
        out.append(Frame(fr.seq, fr.t, lm, fr.joints_world))
        cams.append(cam)
    return out, cams


@dataclass
class MovingCase:
    case: Case                          # camera: the home position; frames: as the moving head saw them
    cameras: list[WorldCamera]          # one per frame
    motion: str
    tilt_at: Callable[[float], float] | None = None   # the head's tilt at any time of the scene (deg down)
    pose_at: Callable[[float], tuple] | None = None   # follow_pan, drive: the camera's yaw, tilt, base acceleration
    track: base_motion.Track | None = None            # follow_pan, drive: every controller step


def case_name(motion: str, name: str) -> str:
    return name if motion == "static" else f"{motion}/{name}"


def _rendered(motion: str, static_frames: Iterable[Frame], camera: WorldCamera, name: str, body: Body, seed: int,
              noise_frac: float, dropouts: tuple = (), follow: FollowHead = FOLLOW, nod: Nod = NOD,
              pan: base_motion.PanTiltHead = base_motion.PAN, drive: base_motion.DriveBase = base_motion.DRIVE):
    """The frames and cameras of one scene under ``motion``, and its head."""
    if motion in base_motion.BASE_MOTIONS:
        static_frames = list(static_frames)
        head = base_motion.head_for(motion, camera, static_frames[0].joints_world if static_frames else None, pan,
                                    drive)
    else:
        head = head_for(motion, camera, name, follow, nod)
    fr, cams = render(static_frames, head, body, seed, noise_frac, dropouts)
    return fr, cams, head


def _moving(case: Case, cams: list[WorldCamera], motion: str, head) -> MovingCase:
    if isinstance(head, base_motion.PanTiltController):
        return MovingCase(case, cams, motion, head.tilt_at, head.pose_at, head.track)
    return MovingCase(case, cams, motion, head.tilt_at)


def moving_cases(splits: Iterable[str], motion: str, shared_data: Path | None = None, only: str = "",
                 follow: FollowHead = FOLLOW, nod: Nod = NOD, pan: base_motion.PanTiltHead = base_motion.PAN,
                 drive: base_motion.DriveBase = base_motion.DRIVE) -> list[MovingCase]:
    """Every case of ``splits`` (tune, heldout, cmu) whose name contains ``only``, seen by the ``motion`` head."""
    if motion not in MOTIONS:
        raise ValueError(f"camera motion {motion!r} is not one of: {', '.join(MOTIONS)}")
    out: list[MovingCase] = []
    for split in splits:
        if split == "cmu":
            if shared_data is None:
                raise ValueError("the CMU clips need the shared data folder")
            for i, c in enumerate(cmu_cases(shared_data / "mocap" / "cmu")):
                if only and only not in c.name:
                    continue
                fr, cams, head = _rendered(motion, c.frames, c.camera, c.name, Body(c.body_height), CMU_SEED + i,
                                           CMU_NOISE, (), follow, nod, pan, drive)
                out.append(_moving(replace(c, name=case_name(motion, c.name), frames=fr), cams, motion, head))
            continue
        for sc in catalogue(split):
            if only and only not in sc.name:
                continue
            fr, cams, head = _rendered(motion, frames(sc), sc.camera, sc.name, sc.body, sc.seed, sc.noise_frac,
                                       sc.dropouts, follow, nod, pan, drive)
            out.append(_moving(Case(case_name(motion, sc.name), sc.kind, split, sc.camera, fr, sc.truth,
                                    sc.body.height), cams, motion, head))
    return out


def imu_downs(mc: MovingCase, rate_hz: float = IMU_RATE_HZ) -> list[tuple[float, float, float] | None]:
    """Each frame's gravity as a camera accelerometer on the head gives it: the head's true down at every sample
    (``mc.tilt_at``, the specific force -g down, no noise: the filter's lag alone) through
    :class:`hal.imu.GravityEstimate`, read at the frame's capture time; None until it has enough samples. A head
    that pans or a base that drives (``mc.pose_at``): the specific force with the base's acceleration
    (:func:`bench.falls_base_motion.base_imu_downs`)."""
    from posed.hal import G_M_S2, GravityEstimate

    if mc.pose_at is not None:
        return base_motion.base_imu_downs(mc, False, rate_hz, GYRO_RATE_HZ, 0.0, 0.0, np.zeros(3), 0)
    est = GravityEstimate()
    tilt_at = mc.tilt_at or (lambda t: mc.case.camera.tilt)
    out = []
    k = 0
    for fr in mc.case.frames:
        while k / rate_hz <= fr.t + 1e-12:
            ts = k / rate_hz
            a = -G_M_S2 * np.asarray(gravity_from_tilt(tilt_at(ts), mc.case.camera.roll), dtype=float)
            est.add(ts, *a)
            k += 1
        out.append(est.at(fr.t))
    return out


def head_rate(tilt0_deg: float, tilt1_deg: float, roll_deg: float, dt: float) -> np.ndarray:
    """The camera's angular rate (rad/s, its own axes: x right, y down, z forward; right-handed), constant over
    ``dt`` seconds, that turns its tilt from ``tilt0_deg`` to ``tilt1_deg``. The head tilts about the room's
    horizontal axis through the camera's sides (:class:`bench.falls_body.WorldCamera`: pan is not simulated),
    which in the axes of a camera rolled by ``roll`` is (cos roll, -sin roll, 0); a tilt down (forward turning
    towards image-down) is a negative turn about it."""
    b = math.radians(roll_deg)
    rate = math.radians(tilt1_deg - tilt0_deg) / dt
    return -rate * np.array([math.cos(b), -math.sin(b), 0.0])


def gyro_bias(name: str, bias_deg_s: float = GYRO_BIAS_DEG_S) -> np.ndarray:
    """A scene's constant gyro bias (rad/s, per axis uniform within +-``bias_deg_s``), drawn from its name."""
    rng = np.random.default_rng(zlib.crc32(("gyro-bias:" + name).encode()))
    return np.radians(rng.uniform(-bias_deg_s, bias_deg_s, 3))


def imu_gyro_downs(mc: MovingCase, rate_hz: float = IMU_RATE_HZ, gyro_hz: float = GYRO_RATE_HZ,
                   noise_density_deg_s: float = GYRO_NOISE_DENSITY_DEG_S, bias_deg_s: float = GYRO_BIAS_DEG_S
                   ) -> list[tuple[float, float, float] | None]:
    """Each frame's gravity as the head's accelerometer and gyroscope give it through
    :class:`hal.imu.GravityEstimate`: the accelerometer as :func:`imu_downs` (the true down at ``rate_hz``, no
    noise); the gyro at ``gyro_hz``, each sample the head's mean angular rate since the previous one
    (:func:`head_rate`) plus white noise of ``noise_density_deg_s * sqrt(gyro_hz / 2)`` per axis and the scene's
    constant bias (:func:`gyro_bias`), the noise drawn from the scene's name. Read at each frame's capture time.
    A head that pans or a base that drives (``mc.pose_at``): the same sensors, the accelerometer feeling the
    base's acceleration and the gyro its yaw (:func:`bench.falls_base_motion.base_imu_downs`)."""
    from posed.hal import G_M_S2, GravityEstimate

    name = mc.case.name.split("/", 1)[1] if mc.motion != "static" else mc.case.name
    bias = gyro_bias(name, bias_deg_s)
    if mc.pose_at is not None:
        return base_motion.base_imu_downs(mc, True, rate_hz, gyro_hz, noise_density_deg_s, bias_deg_s, bias,
                                          zlib.crc32(("gyro-noise:" + mc.case.name).encode()))
    est = GravityEstimate()
    cam = mc.case.camera
    tilt_at = mc.tilt_at or (lambda t: cam.tilt)
    rng = np.random.default_rng(zlib.crc32(("gyro-noise:" + mc.case.name).encode()))
    sigma = math.radians(noise_density_deg_s) * math.sqrt(gyro_hz / 2.0)
    out = []
    k = j = 0
    for fr in mc.case.frames:
        while k / rate_hz <= fr.t + 1e-12:
            ts = k / rate_hz
            est.add(ts, *(-G_M_S2 * np.asarray(gravity_from_tilt(tilt_at(ts), cam.roll), dtype=float)))
            k += 1
        while j / gyro_hz <= fr.t + 1e-12:
            ts = j / gyro_hz
            w = head_rate(tilt_at((j - 1) / gyro_hz), tilt_at(ts), cam.roll, 1.0 / gyro_hz) if j else np.zeros(3)
            est.add_gyro(ts, *(w + bias + rng.normal(0.0, sigma, 3)))
            j += 1
        out.append(est.at(fr.t))
    return out


def true_down(cam: WorldCamera) -> np.ndarray:
    """Gravity in the camera's axes (x right, y down, z forward): what the robot's head joints and the base's
    mount give; the same function the detector turns a configured tilt into."""
    return np.asarray(gravity_from_tilt(cam.tilt, cam.roll), dtype=float)


# ---------------------------------------------------------------------------- scoring


@dataclass
class ArmOutcome:
    outcome: Outcome
    geometry: dict | None = None        # the first falling/on_floor message's extra["geometry"]
    judged: int = 0                     # frames the detector judged
    torso_in_view: int = 0              # frames with the four torso landmarks inside the image
    person_frames: int = 0
    tilt_dev_max_deg: float = 0.0       # the head's largest distance from its home tilt
    tilt_rate_max_deg_s: float = 0.0    # its fastest frame-to-frame change

    def to_json(self) -> dict:
        return {**self.outcome.to_json(), "geometry": self.geometry, "judged_frames": self.judged,
                "torso_in_view_frames": self.torso_in_view, "person_frames": self.person_frames,
                "tilt_dev_max_deg": round(self.tilt_dev_max_deg, 2),
                "tilt_rate_max_deg_s": round(self.tilt_rate_max_deg_s, 1)}


def run_arm(mc: MovingCase, fit: Callable[..., FitResult], cfg: FallsConfig, arm: str,
            fit_frame: str = "auto") -> ArmOutcome:
    """One moving case through ``fit`` (``fit(landmarks, seq, t, image_size, intrinsics, gravity, world)``)
    and a fresh detector under ``arm``; the detector gets the camera's intrinsics (a robot's camera)."""
    if arm not in ARMS:
        raise ValueError(f"arm {arm!r} is not one of: {', '.join(ARMS)}")
    case, base = mc.case, mc.case.camera
    image_size = (base.width, base.height)
    if arm == "measured":
        cfg = replace(cfg, camera_tilt_deg=base.tilt, camera_roll_deg=base.roll, camera_height_m=base.z,
                      camera_geometry="measured")
    det = FallDetector(cfg, "bench", fit_frame=fit_frame)
    if arm in ROBOT_ARMS and not has_camera_mount():
        raise RuntimeError(f"FallDetector has no set_camera_mount: the {arm} arm cannot run")
    mount_down = mount_gravity(cfg) if arm == "measured" else None
    imu = imu_downs(mc) if arm == "imu" else imu_gyro_downs(mc) if arm == "imu_gyro" else None
    messages = []
    failures = judged = in_view = people = 0
    fit_ms: list[float] = []
    lowest = LowestPelvis()
    for k, fr in enumerate(case.frames):
        cam = mc.cameras[k]
        down = true_down(cam) if arm in ROBOT_ARMS else mount_down
        if imu is not None:
            down = None if imu[k] is None else np.asarray(imu[k], dtype=float)
        if fr.landmarks is not None:
            result = fit(fr.landmarks, fr.seq, fr.t, image_size, base.intrinsics, down, None)
            people += 1
            torso = fr.landmarks[list(TORSO)]
            in_view += bool(np.all(torso[:, 3] >= 0.5))
            if not result.ok:
                failures += 1
        else:
            result = FitResult.failure(fr.seq, fr.t, "no person")
        if result.fit_ms is not None:
            fit_ms.append(result.fit_ms)
        if arm in ROBOT_ARMS:
            det.set_camera_mount(down, cam.z if arm == "robot" else None)
        elif arm in ("imu", "imu_gyro") and down is not None:
            det.set_gravity(down)
        messages += det.update(result, fr.landmarks, image_size, intrinsics=base.intrinsics)
        if det.last_features is not None:
            judged += 1
        lowest.add(det.last_sample)
    outcome = outcome_of(case, messages, failures, fit_ms, lowest)
    first = next((m for m in messages if m.state in DETECTING_STATES), None)
    tilts = np.array([c.tilt for c in mc.cameras])
    ts = np.array([fr.t for fr in case.frames])
    rates = np.abs(np.diff(tilts)) / np.maximum(np.diff(ts), 1e-9) if len(ts) > 1 else np.zeros(1)
    return ArmOutcome(outcome, dict(first.extra.get("geometry") or {}) if first is not None else None, judged,
                      in_view, people, float(np.max(np.abs(tilts - base.tilt))), float(np.max(rates, initial=0.0)))


def geometry_label(g: dict | None) -> str:
    if not g:
        return "none"
    return f"gravity {g.get('gravity', '?')}, floor {g.get('floor', '?')}"


def summarise_arm(outs: list[ArmOutcome]) -> dict:
    s = summarise(o.outcome for o in outs)
    s["detected"] = sum(o.outcome.detected for o in outs if o.outcome.kind == "fall")
    s["false_alarm_names"] = [o.outcome.name for o in outs if o.outcome.kind == "adl" and o.outcome.detected]
    s["missed_names"] = [o.outcome.name for o in outs if o.outcome.kind == "fall" and not o.outcome.detected]
    geo: dict[str, dict[str, int]] = {"falls": {}, "false_alarms": {}}
    for o in outs:
        if o.outcome.detected:
            bucket = geo["falls" if o.outcome.kind == "fall" else "false_alarms"]
            label = geometry_label(o.geometry)
            bucket[label] = bucket.get(label, 0) + 1
    s["event_geometry"] = geo
    people = sum(o.person_frames for o in outs)
    s["judged_frames"] = sum(o.judged for o in outs)
    s["person_frames"] = people
    s["torso_in_view"] = round(sum(o.torso_in_view for o in outs) / people, 4) if people else None
    s["splits"] = {sp: summarise(o.outcome for o in outs if o.outcome.split == sp)
                   for sp in dict.fromkeys(o.outcome.split for o in outs)}
    return s


def head_summary(cases: list[MovingCase]) -> dict:
    """How far and how fast the head moved, over every case of one motion."""
    dev = [max(abs(c.tilt - mc.case.camera.tilt) for c in mc.cameras) for mc in cases]
    rate = []
    for mc in cases:
        t = [fr.t for fr in mc.case.frames]
        rate += [abs(b.tilt - a.tilt) / (t1 - t0) for a, b, t0, t1 in
                 zip(mc.cameras[:-1], mc.cameras[1:], t[:-1], t[1:], strict=True) if t1 > t0]
    return {"cases": len(cases),
            "tilt_dev_max_deg": {"median": round(statistics.median(dev), 2) if dev else None,
                                 "max": round(max(dev), 2) if dev else None},
            "tilt_rate_max_deg_s": round(max(rate), 1) if rate else 0.0}


def fit_key(arm: str, motion: str, follow: FollowHead = FOLLOW, nod: Nod = NOD,
            pan: base_motion.PanTiltHead = base_motion.PAN, drive: base_motion.DriveBase = base_motion.DRIVE) -> str:
    """The gravity a case's fit is given, for :func:`bench.falls.cached_fit`'s key: none (default), the measured
    mount's (``given``, as ``posed bench falls --synthetic-geometry given``), or the robot's per-frame one (the
    same as ``given`` for a static head)."""
    if arm == "default":
        return "none"
    if motion in base_motion.BASE_MOTIONS:
        head = f"{motion}:{pan}" + (f":{drive}" if motion == "drive" else "")
    else:
        head = "" if motion == "static" else f"{motion}:{follow if motion == 'follow' else nod}"
    if arm == "imu":
        return f"imu:{IMU_RATE_HZ:g}:{head}"
    if arm == "imu_gyro":
        from posed.hal import GravityEstimate

        tau = GravityEstimate().time_constant_s
        return (f"imu_gyro:{IMU_RATE_HZ:g}:{GYRO_RATE_HZ:g}:{GYRO_NOISE_DENSITY_DEG_S:g}:{GYRO_BIAS_DEG_S:g}:"
                f"{tau:g}:{head}")
    if arm == "measured" or motion == "static":
        return "given"
    return f"robot:{head}"


def findings(results: dict, truth: bool) -> list[str]:
    """Plain sentences where a moving head gives what a user would not expect: fewer falls caught or more false
    alarms than the same arm with the head still, or (without a static run) any miss or false alarm."""
    out = []
    ref = results.get("static")
    what = "ground-truth joints" if truth else "the real fit"
    for motion, arms in results.items():
        for arm, s in arms.items():
            if not isinstance(s, dict) or "falls" not in s:
                continue
            r0 = ref.get(arm) if ref is not None and motion != "static" else None
            caught, n, fa, adl = s["detected"], s["falls"], s["false_alarms"], s["adl"]
            if r0 is not None and isinstance(r0, dict) and "falls" in r0:
                if caught < r0["detected"] or fa > r0["false_alarms"]:
                    out.append(f"{motion} head, {arm} arm ({what}): {caught}/{n} falls caught and {fa}/{adl} "
                               f"false alarms, against {r0['detected']}/{r0['falls']} and {r0['false_alarms']}/"
                               f"{r0['adl']} with the head still: the moving head "
                               + ("misses falls" if caught < r0["detected"] else "")
                               + (" and " if caught < r0["detected"] and fa > r0["false_alarms"] else "")
                               + ("raises false alarms" if fa > r0["false_alarms"] else ""))
            elif n and (caught < n or fa > 0):
                out.append(f"{motion} head, {arm} arm ({what}): {caught}/{n} falls caught, {fa}/{adl} false alarms "
                           "(a user expects every fall and no false alarm)")
            lat = s.get("median_latency_s")
            if lat is not None and lat > LATENCY_TARGET_S:
                out.append(f"{motion} head, {arm} arm ({what}): falls reported a median {lat} s after the impact, "
                           f"over the {LATENCY_TARGET_S:g} s target")
    return out


def run_protocol(motions: Iterable[str], splits: Iterable[str], fit_kind: str = "real", cfg: FallsConfig | None = None,
                 only: str = "", shared_data: Path | None = None, fit_config=None, cache: Path | None = None,
                 arms: Iterable[str] | None = None, progress: Callable[[str, str, ArmOutcome], None] | None = None,
                 follow: FollowHead = FOLLOW, nod: Nod = NOD) -> dict:
    """Every case of ``splits`` seen by each head of ``motions``, scored in each arm (``ARMS``; ``robot`` and
    ``robot_down`` only when the detector has ``set_camera_mount``). ``fit_kind`` "truth": the simulation's joints in each frame's
    camera axes instead of the fit (the detector alone)."""
    cfg = cfg or FallsConfig()
    motions, splits = list(motions), list(splits)
    for m in motions:
        if m not in MOTIONS:
            raise ValueError(f"camera motion {m!r} is not one of: {', '.join(MOTIONS)}")
    arms = list(arms) if arms is not None else list(ARMS)
    skipped = {}
    for arm in ROBOT_ARMS:
        if arm in arms and not has_camera_mount():
            arms.remove(arm)
            skipped[arm] = "FallDetector has no set_camera_mount yet: not run"
    t0 = time.monotonic()
    fit = real_fitter(fit_config) if fit_kind == "real" else None
    fit_frame = "auto" if fit_kind == "real" else "camera"
    results: dict = {}
    heads: dict = {}
    scenarios: dict = {}
    for motion in motions:
        cases = moving_cases(splits, motion, shared_data, only, follow, nod)
        heads[motion] = head_summary(cases)
        if motion in base_motion.BASE_MOTIONS:
            heads[motion]["base"] = base_motion.base_summary(cases)
        results[motion] = {}
        scenarios[motion] = {}
        for arm in arms:
            outs = []
            for mc in cases:
                if fit_kind == "real":
                    fit.reset()  # type: ignore[union-attr]
                    fn = cached_fit(mc.case, fit, fit_config, cache, None,
                                    fit_key(arm, motion, follow, nod, base_motion.PAN, base_motion.DRIVE))
                else:
                    by_seq = {fr.seq: (fr, cam) for fr, cam in zip(mc.case.frames, mc.cameras, strict=True)}

                    def fn(lm, seq, t, size, intr, gravity=None, w=None, by_seq=by_seq):
                        return truth_result(*by_seq[seq])

                o = run_arm(mc, fn, cfg, arm, fit_frame)
                outs.append(o)
                if progress:
                    progress(motion, arm, o)
            results[motion][arm] = summarise_arm(outs)
            scenarios[motion][arm] = [o.to_json() for o in outs]
        for arm, why in skipped.items():
            results[motion][arm] = {"skipped": why}
    return {"protocol": "moving camera", "fit": fit_kind, "splits": splits, "only": only or None,
            "motions": {m: MOTIONS[m] for m in motions}, "arms": {a: ARMS[a] for a in ARMS},
            "follow_head": {"delay_s": follow.delay_s, "tau_s": follow.tau_s, "max_rate_deg_s": follow.max_rate_deg_s,
                            "step_s": follow.step_s},
            "nod": {"amplitude_deg": nod.amplitude_deg, "period_s": nod.period_s},
            **({"pan_tilt_head": base_motion.PAN.__dict__} if set(motions) & set(base_motion.BASE_MOTIONS) else {}),
            **({"drive_base": base_motion.DRIVE.__dict__} if "drive" in motions else {}),
            "set_camera_mount": has_camera_mount(), "head": heads, "results": results,
            "findings": findings(results, fit_kind != "real"), "scenarios": scenarios,
            "seconds": round(time.monotonic() - t0, 1)}


def print_report(report: dict, out=None) -> None:
    """The numbers, plainly."""
    import sys

    out = out or sys.stdout
    fit = "ground-truth joints (the detector alone)" if report["fit"] != "real" else "the real fit"
    print(f"moving camera protocol ({fit}; splits {', '.join(report['splits'])}"
          f"{'; only ' + report['only'] if report['only'] else ''}):", file=out)
    for motion, arms in report["results"].items():
        h = report["head"][motion]
        print(f"{motion}: {report['motions'][motion]}", file=out)
        print(f"  head: {h['cases']} scenes, farthest from home: median {h['tilt_dev_max_deg']['median']} deg, "
              f"max {h['tilt_dev_max_deg']['max']} deg; fastest {h['tilt_rate_max_deg_s']} deg/s", file=out)
        if h.get("base", {}).get("travel_m"):
            b = h["base"]
            print(f"  camera yaw from home: median {b['yaw_from_home_deg']['median']} deg, max "
                  f"{b['yaw_from_home_deg']['max']} deg; base travel: median {b['travel_m']['median']} m, max "
                  f"{b['travel_m']['max']} m; fastest {b['speed_max_m_s']['max']} m/s, hardest "
                  f"{b['accel_max_m_s2']['max']} m/s^2", file=out)
        for arm, s in arms.items():
            if "skipped" in s:
                print(f"  {arm:10} {s['skipped']}", file=out)
                continue
            rec = "  n/a" if s["recall"] is None else f"{100 * s['recall']:5.1f}%"
            geo = "; ".join(f"{k} {v}" for k, v in sorted(s["event_geometry"]["falls"].items(), key=lambda x: -x[1]))
            tiv = "n/a" if s["torso_in_view"] is None else f"{100 * s['torso_in_view']:.1f}%"
            print(f"  {arm:10} falls {s['detected']:3}/{s['falls']:<3} ({rec})  false alarms {s['false_alarms']}/"
                  f"{s['adl']}  median latency {s['median_latency_s']} s  torso in view {tiv}", file=out)
            if geo:
                print(f"             geometry of the falls' events: {geo}", file=out)
            if s["false_alarm_names"]:
                print(f"             false alarms: {', '.join(s['false_alarm_names'])}", file=out)
    if report["findings"]:
        print("not what a user would expect:", file=out)
        for line in report["findings"]:
            print(f"  - {line}", file=out)
    print(f"({report['seconds']} s)", file=out)


__all__ = ["ARMS", "FOLLOW", "GYRO_RATE_HZ", "IMU_RATE_HZ", "MOTIONS", "NOD", "ROBOT_ARMS", "ArmOutcome",
           "FollowController", "FollowHead", "MovingCase", "Nod", "gyro_bias", "has_camera_mount", "head_rate",
           "imu_downs", "imu_gyro_downs", "moving_cases", "print_report", "render", "run_arm", "run_protocol",
           "true_down"]

