"""The fall benchmark: scenarios -> 2D landmarks -> the real fit (video mode) -> the detector -> per-scenario
detected / latency, and recall, false alarms and median latency per split.

Cases: ``scenarios.catalogue("tune")`` (the thresholds were chosen looking at these),
``scenarios.catalogue("heldout")`` (other speeds, views, distances, cameras and seeds; never used to tune),
and the CMU clips 131_01 / 131_02 (real motion capture: walking with a deep crouch) seen by two cameras.

A fall counts as detected by its first ``falling`` or ``on_floor`` message; latency = that message's
``t_detect`` minus the impact time (for a person found lying: minus the first frame). A daily activity with
any message is a false alarm.
"""

from __future__ import annotations

import math
import statistics
import time
import zlib
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from posed.bench.bvh import cmu_landmark_world, read_bvh
from posed.bench.falls_body import Body, WorldCamera
from posed.bench.falls_extractor import EXTRACTORS, as_extractor
from posed.bench.falls_scenarios import Frame, Truth, catalogue, frames, truth_result
from posed.bench.falls_world import MEANING as WORLD_MEANING
from posed.bench.falls_world import case_world
from posed.camera_model import Intrinsics
from posed.daemon.stages.fit import mount_gravity
from posed.falls.config import FallsConfig
from posed.falls.detector import FallDetector
from posed.falls.features import gravity_from_tilt
from posed.fitting import FitResult

DETECTING_STATES = ("falling", "on_floor")


@dataclass
class Case:
    name: str
    kind: str
    split: str
    camera: WorldCamera
    frames: list[Frame]
    truth: Truth
    body_height: float = 1.65


@dataclass
class Outcome:
    name: str
    kind: str
    split: str
    detected: bool
    latency_s: float | None
    states: list[str] = field(default_factory=list)
    frames: int = 0
    fit_failures: int = 0
    fit_ms_mean: float = 0.0
    min_pelvis_rel: float | None = None         # lowest relative pelvis height seen (median of 3 frames)
    min_pelvis_rel_lying: float | None = None   # the same while the trunk was more than 60 deg from vertical

    def to_json(self) -> dict:
        return {"name": self.name, "kind": self.kind, "split": self.split, "detected": self.detected,
                "latency_s": None if self.latency_s is None else round(self.latency_s, 3),
                "states": self.states, "frames": self.frames, "fit_failures": self.fit_failures,
                "fit_ms_mean": round(self.fit_ms_mean, 2),
                "min_pelvis_rel": None if self.min_pelvis_rel is None else round(self.min_pelvis_rel, 3),
                "min_pelvis_rel_lying": None if self.min_pelvis_rel_lying is None else round(self.min_pelvis_rel_lying, 3)}


def scenario_cases(split: str, mount: str = "robot") -> list[Case]:
    out = []
    prefix = "" if mount == "robot" else f"{mount}/"
    for sc in catalogue(split, mount):
        out.append(Case(sc.name, sc.kind, prefix + split, sc.camera, list(frames(sc)), sc.truth, sc.body.height))
    return out


# The CMU clips' cameras per mount: (distance from the middle of the path (m), height (m), tilt (deg),
# width, height (px), horizontal field of view (deg)). The wall camera is nearer: at 35 deg down its image
# starts 11 deg below the horizon, so shoulders further than ~2.8 m are cut off.
CMU_MOUNTS = {"robot": (4.0, 1.0, 12.0, 640, 480, 69.0), "wall": (2.6, 2.0, 35.0, 320, 240, 62.0),
              "corner": (3.6, 2.4, 25.0, 320, 240, 74.0)}


def cmu_cases(data_dir: Path, fps: float = 10.0, noise_frac: float = 0.01, seed: int = 77,
              mount: str = "robot") -> list[Case]:
    """The two CMU clips, each seen from the side and at 45 degrees (robot: 4 m from the middle of the path,
    camera 1 m high, 12 deg down; wall: ``CMU_MOUNTS``)."""
    if mount not in CMU_MOUNTS:
        raise ValueError(f"mount {mount!r} is not one of: {', '.join(CMU_MOUNTS)}")
    dist, cam_z, tilt, width, height_px, hfov = CMU_MOUNTS[mount]
    prefix = "" if mount == "robot" else f"{mount}/"
    out = []
    for clip in ("131_01", "131_02"):
        path = data_dir / f"{clip}.bvh"
        if not path.is_file():
            raise FileNotFoundError(f"{path} is missing: the CMU clips live in shared/data/mocap/cmu "
                                    "(set POSED_SHARED_DATA or run from the project root)")
        motion = read_bvh(path)
        step = max(1, int(round(motion.fps / fps)))
        idx = np.arange(0, motion.data.shape[0], step)
        world = cmu_landmark_world(motion, idx)
        pelvis = np.array([p["pelvis"][:2] for p in world])
        centre = pelvis.mean(0)
        heading = pelvis[-1] - pelvis[0]
        heading = heading / max(float(np.linalg.norm(heading)), 1e-9)
        side = np.array([-heading[1], heading[0]])
        nose = max(p["nose"][2] for p in world[:3])
        height = nose / 0.93
        for view, direction in (("side", side), ("oblique", (side + heading) / math.sqrt(2))):
            pos = centre + dist * direction
            d = centre - pos
            cam = WorldCamera(x=float(pos[0]), y=float(pos[1]), z=cam_z, tilt=tilt,
                              yaw=math.degrees(math.atan2(-d[0], d[1])), width=width, height=height_px, hfov=hfov)
            rng = np.random.default_rng(seed + len(out))
            body = Body(height)
            fr = [Frame(k, k * step / motion.fps, cam.project(p, body, rng, noise_frac), p)
                  for k, p in enumerate(world)]
            out.append(Case(f"{prefix}cmu/{clip}/{view}", "adl", f"{prefix}cmu", cam, fr, Truth("adl"), height))
    return out


IMU_BIAS_DEG = 0.5    # rms error of a calibrated accelerometer's down direction, constant over a scene (per axis)
IMU_NOISE_DEG = 0.05  # rms frame-to-frame noise of the filtered direction (tests/hal/test_imu.py: ~0.1 at 3 sigma)

# How the detector learns the synthetic camera's tilt and roll (its height is given, except "default"):
GEOMETRIES = {
    "default": "the config as it is (tilt and roll 0, camera height 1 m unless set): a freshly started daemon "
               "that was told nothing about the camera",
    "given": "the scene's true tilt and roll in the config",
    "unknown": "tilt and roll 0 in the config (a mount nobody measured), nothing learned",
    "auto": "tilt and roll 0 in the config, learned from the person (camera_tilt_auto, camera_roll_auto)",
    "imu": "tilt and roll 0 in the config; every frame carries the accelerometer's gravity (the true one, off "
           f"by a constant {IMU_BIAS_DEG} deg rms bias per scene and {IMU_NOISE_DEG} deg rms noise per frame, per "
           "axis), as FallWatch passes it",
}


def _imu_gravity(cam, rng: np.random.Generator, bias_rad: np.ndarray) -> np.ndarray:
    """The true down direction of ``cam`` turned by the scene's bias and a frame's noise (radians, 2 axes)."""
    g = np.asarray(gravity_from_tilt(cam.tilt, cam.roll), dtype=float)
    err = bias_rad + rng.normal(0.0, math.radians(IMU_NOISE_DEG), 2)
    tilted = g + err[0] * np.cross(g, [1.0, 0.0, 0.0]) + err[1] * np.cross(g, [0.0, 0.0, 1.0])
    return tilted / np.linalg.norm(tilted)


def run_case(case: Case, fit: Callable[..., FitResult], cfg: FallsConfig, fit_frame: str, geometry: str = "given",
             intrinsics: bool = True, world: list | None = None) -> Outcome:
    """One case through ``fit`` and a fresh detector. ``fit(landmarks, seq, t, image_size, intrinsics,
    gravity, world)``: gravity the IMU's (geometry imu) or the measured mount's (given), else None, as the daemon's
    fitting stage gives it; ``world`` the frame's world landmarks from ``world`` (one per frame:
    :func:`bench.falls_world.case_world`), or None. ``intrinsics`` False: the detector is given none (a
    recording without a camera header: it assumes ``camera_hfov_deg``)."""
    cam = case.camera
    image_size = (cam.width, cam.height)
    if geometry not in GEOMETRIES:
        raise ValueError(f"geometry {geometry!r} is not one of: {', '.join(GEOMETRIES)}")
    if geometry == "given":
        cfg = replace(cfg, camera_tilt_deg=cam.tilt, camera_roll_deg=cam.roll, camera_height_m=cam.z,
                      camera_geometry="measured")
    elif geometry != "default":
        cfg = replace(cfg, camera_tilt_deg=0.0, camera_roll_deg=0.0,
                      camera_tilt_auto=geometry == "auto", camera_roll_auto=geometry == "auto", camera_height_m=cam.z)
    det = FallDetector(cfg, "bench", fit_frame=fit_frame)
    imu_rng = np.random.default_rng(zlib.crc32(case.name.encode())) if geometry == "imu" else None
    imu_bias = imu_rng.normal(0.0, math.radians(IMU_BIAS_DEG), 2) if imu_rng is not None else None
    messages = []
    failures = 0
    fit_ms = []
    lowest = LowestPelvis()
    # the fit is given the down the daemon's fitting stage gives it (daemon.stages.fit.frame_gravity): the IMU's,
    # else the measured mount's (geometry given: cfg measured above)
    mount_down = mount_gravity(cfg) if geometry == "given" else None
    for k, fr in enumerate(case.frames):
        imu = _imu_gravity(cam, imu_rng, imu_bias) if imu_rng is not None else None
        result = fit(fr.landmarks, fr.seq, fr.t, image_size, cam.intrinsics, imu if imu is not None else mount_down,
                     world[k] if world is not None else None) \
            if fr.landmarks is not None else FitResult.failure(fr.seq, fr.t, "no person")
        if fr.landmarks is not None and not result.ok:
            failures += 1
        if result.fit_ms is not None:
            fit_ms.append(result.fit_ms)
        if imu is not None:
            det.set_gravity(imu)
        messages += det.update(result, fr.landmarks, image_size, intrinsics=cam.intrinsics if intrinsics else None)
        lowest.add(det.last_sample)
    return outcome_of(case, messages, failures, fit_ms, lowest)


class LowestPelvis:
    """The lowest pelvis height a case reached (the detector's ``h_rel``, median of its last 3 samples), overall
    and while lying (trunk inclination above 60 deg)."""

    def __init__(self) -> None:
        self.recent: list = []
        self.low: float | None = None
        self.low_lying: float | None = None

    def add(self, sample) -> None:
        """The detector's ``last_sample`` of a frame (None: nothing judged)."""
        if sample is None:
            return
        self.recent = (self.recent + [sample])[-3:]
        h = float(np.median([x.h_rel for x in self.recent]))
        incl = float(np.median([x.incl for x in self.recent]))
        self.low = h if self.low is None else min(self.low, h)
        if incl > 60:
            self.low_lying = h if self.low_lying is None else min(self.low_lying, h)


def outcome_of(case: Case, messages: list, failures: int, fit_ms: list[float], lowest: LowestPelvis) -> Outcome:
    """A case's outcome from the detector's messages: caught (a detecting state), latency from the impact."""
    first = next((m for m in messages if m.state in DETECTING_STATES), None)
    latency = None
    if first is not None and case.kind == "fall":
        latency = first.t_detect - (case.truth.t_impact if case.truth.t_impact is not None else 0.0)
    return Outcome(case.name, case.kind, case.split, first is not None, latency, [m.state for m in messages],
                   len(case.frames), failures, float(np.mean(fit_ms)) if fit_ms else 0.0, lowest.low,
                   lowest.low_lying)


def summarise(outcomes: Iterable[Outcome]) -> dict:
    outcomes = list(outcomes)
    falls = [o for o in outcomes if o.kind == "fall"]
    adl = [o for o in outcomes if o.kind == "adl"]
    lat = [o.latency_s for o in falls if o.detected and o.latency_s is not None]
    return {
        "falls": len(falls), "adl": len(adl),
        "recall": (sum(o.detected for o in falls) / len(falls)) if falls else None,
        "false_alarms": sum(o.detected for o in adl),
        "median_latency_s": round(statistics.median(lat), 3) if lat else None,
        "max_latency_s": round(max(lat), 3) if lat else None,
    }


def real_fitter(fit_config=None):
    """``fit(landmarks, seq, t, image_size, intrinsics)`` through fitting.fitter.Fitter in video mode; with
    intrinsics the fit projects through the pinhole (``fitting.projection: auto``), as with a RealSense, or
    through an assumed lens (``Intrinsics.assume``), as the daemon fits a source without intrinsics."""
    from posed.fitting import FitConfig, Fitter

    fitter = Fitter(fit_config or FitConfig())
    fitter.warmup()

    def fit(landmarks, seq, t, image_size, intrinsics, gravity=None, world=None):
        return fitter.fit(landmarks, seq, t, image_size, mode="video", intrinsics=intrinsics, gravity=gravity,
                          world=world)

    fit.reset = fitter.reset  # type: ignore[attr-defined]
    return fit


def cached_fit(case: Case, fit, fit_config, cache: Path | None, intrinsics: Intrinsics | None = None,
               down: str = "none", world: bool = False):
    """``fit`` wrapped with a per-case cache of its results (key: the case's landmarks, the fit config, the
    intrinsics the fit is given, ``down`` (which gravity the fit is given: none, given or imu; each is the same
    for a case every time) and the fitting package's source), so that re-scoring the detector costs no
    fit. ``intrinsics``: given to the fit instead of the case camera's (an assumed lens); ``world``: the fit is
    given the case's simulated world landmarks (:mod:`bench.falls_world`, part of the key)."""
    if cache is None:
        return lambda lm, seq, t, size, intr, gravity=None, w=None: fit(lm, seq, t, size, intrinsics or intr, gravity, w)
    import hashlib
    import json
    from dataclasses import asdict

    from posed.bench.falls_recordings import _fitting_source_hash
    from posed.daemon.bus.payloads import dumps

    h = hashlib.sha256()
    for fr in case.frames:
        h.update(b"none" if fr.landmarks is None else np.ascontiguousarray(fr.landmarks, float).tobytes())
    h.update(json.dumps(asdict(fit_config) if fit_config is not None else {}, sort_keys=True).encode())
    h.update(f"{intrinsics or case.camera.intrinsics}{_fitting_source_hash()}".encode())
    if down != "none":   # (keys of fits without gravity as before)
        h.update(f"down={down}".encode())
    if world:            # (and of fits without world landmarks): the stream's error model is part of it
        import inspect

        from posed.bench import falls_world, world_sim
        h.update(f"world={inspect.getsource(world_sim)}{inspect.getsource(falls_world)}".encode())
    path = cache / f"{case.name.replace('/', '_')}.{h.hexdigest()[:20]}.fits.jsonl"
    stored = None
    if path.is_file():
        stored = [FitResult.from_json(json.loads(line)) for line in path.read_text().splitlines()]
        if len(stored) != sum(fr.landmarks is not None for fr in case.frames):
            stored = None
    if stored is not None:
        it = iter(stored)
        return lambda lm, seq, t, size, intr, gravity=None, w=None: next(it)
    made: list[FitResult] = []

    def fn(lm, seq, t, size, intr, gravity=None, w=None):
        r = fit(lm, seq, t, size, intrinsics or intr, gravity, w)
        made.append(r)
        if len(made) == sum(fr.landmarks is not None for fr in case.frames):
            path.parent.mkdir(parents=True, exist_ok=True)
            tmp = path.with_suffix(".tmp")
            tmp.write_text("".join(dumps(x.to_json()) + "\n" for x in made))
            tmp.replace(path)
        return r

    return fn


def fit_down(geometry: str, fit_config=None) -> str:
    """Which gravity a scenario's fit is given under ``geometry`` (run_case): the IMU's (imu), the measured
    mount's (given), or none; none whatever the geometry when ``fitting.vertical`` is camera."""
    if fit_config is not None and fit_config.vertical == "camera":
        return "none"
    return geometry if geometry in ("given", "imu") else "none"


def run_bench(splits: Iterable[str], fit_kind: str = "real", cfg: FallsConfig | None = None,
              only: str = "", shared_data: Path | None = None, progress: Callable[[Outcome], None] | None = None,
              fit_config=None, with_intrinsics: bool = True, cache: Path | None = None,
              geometry: str = "given", mount: str = "robot", world: bool = False,
              extractor: str = "blazepose") -> dict:
    """``with_intrinsics`` False, and always with a ``mount`` other than "robot" (the scenarios and CMU clips seen
    by ``falls_scenarios.MOUNTS["wall"]`` or ``["corner"]``, as a recording without a camera header): the fit is given what the
    daemon gives a source without intrinsics, the assumed lens of ``camera_hfov_deg`` (orthographic when
    ``fit_config.projection`` is), not the camera's true one. With a wall camera the detector gets no
    intrinsics either (it assumes the same lens). ``world``: the real fit is given each case's simulated world
    landmarks (:mod:`bench.falls_world`), as the daemon's landmark stage gives them. ``extractor``: the 2D
    landmarks as that extractor gives them (:mod:`bench.falls_extractor`; "holistic": as the real recordings of
    urfd_dev, which carry no world landmarks, so not with ``world``)."""
    if extractor not in EXTRACTORS:
        raise ValueError(f"extractor {extractor!r} is not one of: {', '.join(EXTRACTORS)}")
    if world and extractor != "blazepose":
        raise ValueError(f"world landmarks come from BlazePose: --world cannot go with --extractor {extractor} "
                         "(drop one of them)")
    cfg = cfg or FallsConfig()
    cases: list[Case] = []
    if mount != "robot":
        with_intrinsics = False
    for split in splits:
        if split == "cmu":
            cases += cmu_cases(shared_data / "mocap" / "cmu", mount=mount)
        else:
            cases += scenario_cases(split, mount)
    if only:
        cases = [c for c in cases if only in c.name]
    cases = [as_extractor(c, extractor) for c in cases]
    outcomes = []
    t0 = time.monotonic()
    fit = real_fitter(fit_config) if fit_kind == "real" else None
    fit_frame = "auto" if fit_kind == "real" else "camera"
    for case in cases:
        if fit_kind == "real":
            fit.reset()  # type: ignore[union-attr]
            assumed = None if with_intrinsics else \
                Intrinsics.assume(cfg.camera_hfov_deg, case.camera.width, case.camera.height)
            fn = cached_fit(case, fit, fit_config, cache, assumed, fit_down(geometry, fit_config), world)
        else:
            by_seq = {fr.seq: fr for fr in case.frames}

            def fn(lm, seq, t, size, intr, gravity=None, w=None, by_seq=by_seq, cam=case.camera):
                return truth_result(by_seq[seq], cam)

        outcome = run_case(case, fn, cfg, fit_frame, geometry, intrinsics=mount == "robot",
                           world=case_world(case) if world and fit_kind == "real" else None)
        outcomes.append(outcome)
        if progress:
            progress(outcome)
    report = {"scenarios": [o.to_json() for o in outcomes], **summarise(outcomes)}
    report["splits"] = {s: summarise(o for o in outcomes if o.split == s) for s in dict.fromkeys(o.split for o in outcomes)}
    orthographic = fit_config is not None and fit_config.projection == "orthographic"
    report["fit"] = fit_kind if fit_kind != "real" else (
        "real, orthographic (fitting.projection orthographic)" if orthographic
        else "real, perspective (intrinsics given)" if with_intrinsics
        else f"real, perspective through the assumed {cfg.camera_hfov_deg:g} deg lens (no intrinsics given)")
    report["geometry"] = {"mode": geometry, "meaning": GEOMETRIES[geometry]}
    report["mount"] = mount
    report["world"] = WORLD_MEANING if world and fit_kind == "real" else None
    report["extractor"] = {"name": extractor, "meaning": EXTRACTORS[extractor]}
    report["seconds"] = round(time.monotonic() - t0, 1)
    return report
