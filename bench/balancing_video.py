"""Protocol ``balancing_video`` of ``posed bench fit``: the fit on real video against real 3D, beside the 3D a
MediaPipe user already has (BlazePose's own world landmarks) on the same frames.

Data (../shared/data/reference/pose2sim_demo, Pose2Sim's demo, BSD-3-Clause): one man balancing on one leg,
arms moving, filmed by 4 calibrated, synchronised cameras (portrait full HD, 60 fps, 100 frames each); his 3D
joints triangulated from all four views (markerless: a floor of 2-3 cm, errors shared with a 2D detector).
Each view goes through posed's own landmark stage (``posed landmarks``: BlazePose full, video mode, the world
landmarks kept), its pixels are undistorted with the calibration, and the fit gets the camera's true
intrinsics, the default config otherwise (no height given: video mode learns the proportions), at the
daemon's 10 fps (every 6th frame: the landmark stage itself sees only those, as the daemon's does on a
faster camera; six runs, one per starting frame 0-5, so that every frame is scored once and the 10 fps rows
weigh as many frames as the 60 fps one) in video and image mode, and at the video's 60 fps in video mode. The comparison is
BlazePose's world landmarks as a MediaPipe user has them: the same landmark stage run with
``landmarks.keep_sides=false`` (posed puts back left and right where BlazePose flips them between two
frames, landmarks.sides; a MediaPipe user does not have that).

Per frame where both the fit and BlazePose answered (the same frames for both), on the 12 body joints
(shoulders, elbows, wrists, hips, knees, ankles) in the camera frame: PA-MPJPE (similarity-aligned, mm),
MPJPE with the mid-hips together but no rotation (mm: depth order counts), limb depth flips (limb segments
whose true depth difference exceeds 5 cm and whose estimate has the other sign), the 8 angles from 3D joint
positions (the same formula for truth and estimate, ``bench.ood.segment_angles``; also each angle's mean absolute
and signed error, ``per_angle_deg``: a joint read less bent than it is shows as a negative ``signed``), and for the fit also the
mid-hip's position (``root_cam_m``) against the truth and the four views' agreement on it (the spread of the
four world positions). Baseline: the 2D landmarks with zero depth (PA-MPJPE).

Where the error comes from (``depth_sources``, PA-MPJPE mm): posed's own 2D landmarks, back-projected through
the camera, each at a depth taken from elsewhere -- the true depth of each joint (``true``: what the 2D
landmarks and the keypoint definitions leave, the floor of any estimate built on them), the true mid-hip
depth plus BlazePose's world depths relative to its mid-hip (``world``), or plus the fit's (``fit``). The
gap between ``true`` and the others is what each source's depths cost.

Which way is down (fitting.vertical): the video mode 10 fps run is made a second time with each camera's
gravity, from its calibration (the world's z is up), given to the fit, as a camera's IMU gives it (the row's
``gravity``: calibration). The cameras look 18-25 degrees down and are rolled by up to 26. The scores above
cannot see it (the pelvis tilt, traded against lumbar and hip flexion, moves no joint); what can is whether
the four views agree on that split: ``views_split_spread_deg``, per reported angle (``theta_hp_l``,
``theta_hp_r``, ``theta_tr``), the spread (standard deviation) of the four views' values on a frame, the mean
over the frames every view answered.
"""

from __future__ import annotations

import contextlib
import json
import sys
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from posed.bench import ood as O
from posed.bench.landmark_cache import stage_tag
from posed.bench.mocap_landmarks import BODY12, BODY12_IDX
from posed.camera_model import Intrinsics
from posed.fitting import FitConfig, Fitter
from posed.landmarks import read_recording

PROTOCOL = "balancing_video"
DOMAIN = "real video"
DATA = Path("reference") / "pose2sim_demo"
CAMERAS = ("cam01", "cam02", "cam03", "cam04")
VIDEO_FPS = 60.0
RUNS = (("video", 10.0), ("image", 10.0), ("video", 60.0))   # (mode, fps): the daemon's rate, and every frame
EXTERNAL_RUN = ("video", 10.0)   # the run that also fits other extractors' recordings as `posed fit` does
GRAVITY_RUN = ("video", 10.0)    # run again with each camera's gravity (from its calibration) given to the fit
SPLIT_ANGLES = ("theta_hp_l", "theta_hp_r", "theta_tr")   # the fit's pelvis / hip / lumbar split (fitting.vertical)
WORLD_UP = np.array([0.0, 0.0, 1.0])   # the calibration's world z points up (the man's ankles -> shoulders)
# posed's joint names -> the triangulated markers' names (truth_3d.trc)
TRC_NAMES = {"left_shoulder": "LShoulder", "right_shoulder": "RShoulder", "left_elbow": "LElbow",
             "right_elbow": "RElbow", "left_wrist": "LWrist", "right_wrist": "RWrist", "left_hip": "LHip",
             "right_hip": "RHip", "left_knee": "LKnee", "right_knee": "RKnee", "left_ankle": "LAnkle",
             "right_ankle": "RAnkle"}


@dataclass(frozen=True)
class Camera:
    """One calibrated view: ``k`` intrinsics matrix, ``dist`` OpenCV distortion, ``rot`` (3, 3) and ``t`` (3,)
    taking world points (m) into the camera frame (x right, y down, z forward): p_cam = rot @ p_world + t."""

    name: str
    k: np.ndarray
    dist: np.ndarray
    rot: np.ndarray
    t: np.ndarray

    def to_camera(self, p_world: np.ndarray) -> np.ndarray:
        return np.asarray(p_world, float) @ self.rot.T + self.t

    def to_world(self, p_cam: np.ndarray) -> np.ndarray:
        return (np.asarray(p_cam, float) - self.t) @ self.rot

    def intrinsics(self, image_size: tuple[int, int]) -> Intrinsics:
        return Intrinsics(float(self.k[0, 0]), float(self.k[1, 1]), float(self.k[0, 2]), float(self.k[1, 2]),
                          int(image_size[0]), int(image_size[1]))

    def undistort(self, landmarks: np.ndarray) -> np.ndarray:
        """(33, 5) landmark rows with their pixels moved to where a distortion-free camera sees them."""
        out = np.array(landmarks, float)
        ok = np.isfinite(out[:, :2]).all(axis=1)
        if ok.any():
            pts = cv2.undistortPoints(out[ok, :2].reshape(-1, 1, 2), self.k, self.dist, P=self.k)
            out[ok, :2] = pts.reshape(-1, 2)
        return out


def load_cameras(folder: Path) -> dict[str, Camera]:
    """The four views of calibration.toml (rotation as a Rodrigues vector)."""
    cal = tomllib.loads((folder / "calibration.toml").read_text())
    out = {}
    for name in CAMERAS:
        c = cal[f"cam_{name[3:]}"]
        rot, _ = cv2.Rodrigues(np.asarray(c["rotation"], float))
        out[name] = Camera(name, np.asarray(c["matrix"], float), np.asarray(c["distortions"], float), rot,
                           np.asarray(c["translation"], float))
    return out


def load_trc(folder: Path) -> tuple[list[str], np.ndarray]:
    """Every point of truth_3d.trc: its names (``RHip``, ..., ``Head``, ``Nose``, ...) and (frames, points, 3)
    in the calibration's world frame, metres; a .trc point (X, Y, Z) is the world point (Z, X, Y) (data README)."""
    lines = (folder / "balancing" / "truth_3d.trc").read_text().splitlines()
    names = [n for n in lines[3].split("\t")[2:] if n]
    rows = [ln.split("\t") for ln in lines[5:] if ln.strip()]
    data = np.array([[float(v) for v in r[2:2 + 3 * len(names)]] for r in rows]).reshape(len(rows), len(names), 3)
    return names, data[:, :, [2, 0, 1]]


def load_truth(folder: Path) -> np.ndarray:
    """(frames, 12, 3) the 12 body joints (``BODY12`` order) in the calibration's world frame, metres."""
    names, data = load_trc(folder)
    return data[:, [names.index(TRC_NAMES[n]) for n in BODY12]]


def landmark_recording(video: Path, cache: Path, *, mediapipe_sides: bool = False, step: int = 1,
                       phase: int = 0) -> Path:
    """posed's own landmark stage on one view, cached beside the other bench inputs under a name that changes
    with the landmark stage's code. ``step`` 1: every frame (``posed landmarks``); ``step`` n: every n-th frame
    only from frame ``phase`` on, as the daemon's landmark stage sees a faster camera (its seq and time kept:
    ``t = seq / 60``).
    ``mediapipe_sides``: with BlazePose's left/right labels as they come (``landmarks.keep_sides=false``: what
    a MediaPipe user has)."""
    tag = (stage_tag() + (f".every{step}" if step > 1 else "") + (f"+{phase}" if phase else "")
           + (".mediapipe" if mediapipe_sides else ""))
    out = cache / f"{video.stem}.{tag}.landmarks.jsonl"
    if out.is_file() and out.stat().st_mtime >= video.stat().st_mtime:
        return out
    out.parent.mkdir(parents=True, exist_ok=True)
    sets = ["--set", "landmarks.keep_sides=false"] if mediapipe_sides else []
    if step == 1:
        from posed.cli import main

        with contextlib.redirect_stdout(sys.stderr):
            if main(["landmarks", str(video), "-o", str(out), *sets]) != 0:
                raise RuntimeError(f"posed landmarks failed on {video}")
        return out
    from posed.landmarks import LandmarkConfig, MultiPoseLandmarker, RecordingHeader, write_recording

    landmarker = MultiPoseLandmarker(LandmarkConfig(keep_sides=not mediapipe_sides))
    cap = cv2.VideoCapture(str(video))
    frames, seq, size = [], 0, None
    try:
        while True:
            ok, image = cap.read()
            if not ok:
                break
            if seq == 0:
                size = (image.shape[1], image.shape[0])
            if seq % step == phase:
                frames.append(landmarker.process(image, seq / VIDEO_FPS, seq))
            seq += 1
    finally:
        cap.release()
    if size is None:
        raise RuntimeError(f"{video}: no frame could be read")
    write_recording(out, RecordingHeader(size, VIDEO_FPS / step,
                                         source=f"bench {PROTOCOL} {video.name} every {step}th frame from {phase}"),
                    frames)
    return out


@dataclass
class _View:
    camera: Camera
    image_size: tuple[int, int]
    landmarks: list[np.ndarray | None]        # undistorted (33, 5) per frame, None: no person
    world: list[np.ndarray | None]            # the world landmarks (33, 5) per frame the fit is given
    truth_cam: np.ndarray                     # (frames, 12, 3) camera frame
    baseline_world: list[np.ndarray | None] | None = None   # BlazePose's, labels as they come (the baseline)


def _load_view(camera: Camera, recording: Path, truth_world: np.ndarray,
               baseline: Path | None = None) -> _View:
    """One view: posed's ``recording`` (what the fit gets) and, when given, the ``baseline`` recording whose
    world landmarks are the comparison (else the recording's own)."""
    n = len(truth_world)

    def by_seq(path: Path) -> tuple[tuple[int, int], list, list]:
        """Landmarks (undistorted) and world landmarks per video frame (None where the recording has none)."""
        header, frames, problems = read_recording(path)
        if problems:
            raise RuntimeError(f"{path}: {problems[0]}")
        lms: list = [None] * n
        world: list = [None] * n
        for f in frames:
            if 0 <= f.seq < n:
                lms[f.seq] = None if f.landmarks is None else camera.undistort(f.landmarks)
                world[f.seq] = f.world
        return tuple(header.image_size), lms, world

    size, lms, world = by_seq(recording)
    base = None if baseline is None else by_seq(baseline)[2]
    return _View(camera, size, lms, world, camera.to_camera(truth_world), base)


def _mid_hip(j: np.ndarray) -> np.ndarray:
    return 0.5 * (j[BODY12.index("left_hip")] + j[BODY12.index("right_hip")])


class _Scores:
    """Per-frame errors of one estimate (mm, degrees, flips)."""

    def __init__(self) -> None:
        self.pa: list[float] = []
        self.rel: list[float] = []
        self.angle: list[float] = []
        self.angle_signed: list[np.ndarray] = []   # per frame, estimate - truth for each of O.ANGLE_NAMES
        self.flips = [0, 0]
        self.per_joint: list[np.ndarray] = []

    def add(self, est: np.ndarray, truth: np.ndarray) -> None:
        aligned = O.procrustes_align(est, truth)
        self.per_joint.append(np.linalg.norm(aligned - truth, axis=1) * 1e3)
        self.pa.append(float(self.per_joint[-1].mean()))
        self.rel.append(O.mpjpe(est - _mid_hip(est), truth - _mid_hip(truth)) * 1e3)
        self.angle_signed.append(O.segment_angles(est) - O.segment_angles(truth))
        self.angle.append(float(np.abs(self.angle_signed[-1]).mean()))
        f, c = O.depth_flips(est, truth)
        self.flips[0] += f
        self.flips[1] += c

    def summary(self) -> dict:
        if not self.pa:
            return {}
        joints = np.mean(self.per_joint, axis=0)
        return {"pa_mpjpe_mm": round(float(np.mean(self.pa)), 1), "pa_mpjpe_median_mm": round(float(np.median(self.pa)), 1),
                "mpjpe_hip_aligned_mm": round(float(np.mean(self.rel)), 1),
                "angle_err_deg": round(float(np.mean(self.angle)), 2),
                "depth_flips": round(self.flips[0] / max(self.flips[1], 1), 3),
                "per_joint_pa_mm": {n: round(float(v), 1) for n, v in zip(BODY12, joints, strict=True)},
                "per_angle_deg": _per_angle(np.array(self.angle_signed))}


def _per_angle(signed: np.ndarray) -> dict[str, dict[str, float]]:
    """Each of the 8 angles (``bench.ood.ANGLE_NAMES``): mean absolute error (``abs``) and mean signed error
    (``signed``: estimate - truth; negative reads the joint less bent than it is), degrees, over the frames
    ``signed`` holds (one row each)."""
    return {n: {"abs": round(float(np.abs(signed[:, k]).mean()), 1), "signed": round(float(signed[:, k].mean()), 1)}
            for k, n in enumerate(O.ANGLE_NAMES)}


@dataclass
class _Pool:
    """Everything one view's runs are scored into."""

    fit: _Scores = field(default_factory=_Scores)
    world: _Scores = field(default_factory=_Scores)
    flat: _Scores = field(default_factory=_Scores)
    depth_from: dict[str, _Scores] = field(default_factory=lambda: {s: _Scores() for s in ("true", "world", "fit")})
    root_err: list[float] = field(default_factory=list)
    roots: dict[int, np.ndarray] = field(default_factory=dict)   # frame -> the fit's mid-hip in the world
    split: dict[int, np.ndarray] = field(default_factory=dict)   # frame -> the fit's SPLIT_ANGLES (degrees)
    frames: int = 0
    answered: int = 0


def _fit_view(runs: list[_View], mode: str, fps: float, base: FitConfig, gravity: bool = False) -> dict:
    """One view's scores at ``fps``, pooled over its ``runs`` (one per starting frame: run p fits frames p,
    p + step, ...; each a fresh fitter, as a daemon started at that frame); ``gravity``: the fit is given the
    camera's gravity (from the calibration, as an IMU would give it)."""
    step = round(VIDEO_FPS / fps)
    pool = _Pool()
    for phase, view in enumerate(runs):
        _fit_run(view, phase, step, mode, base, pool, gravity)
    return {"frames": pool.frames, "answered": pool.answered, "fit": pool.fit.summary(),
            "blazepose_world": pool.world.summary(), "flat_2d": {"pa_mpjpe_mm": pool.flat.summary().get("pa_mpjpe_mm")},
            "depth_sources": {s: sc.summary().get("pa_mpjpe_mm") for s, sc in pool.depth_from.items()},
            "root_err_mm": round(float(np.median(pool.root_err)), 1) if pool.root_err else None, "_roots": pool.roots,
            "_split": pool.split}


def _fit_run(view: _View, phase: int, step: int, mode: str, base: FitConfig, pool: _Pool,
             gravity: bool = False) -> None:
    """Frames ``phase``, ``phase + step``, ... of one view through a fresh fitter, scored into ``pool``."""
    fitter = Fitter(base)
    k = view.camera.intrinsics(view.image_size)
    down = view.camera.rot @ -WORLD_UP if gravity else None
    for i in range(phase, len(view.landmarks), step):
        pool.frames += 1
        lm = view.landmarks[i]
        w = view.world[i]
        r = fitter.fit(lm, i, i / VIDEO_FPS, view.image_size, mode=mode, intrinsics=k, world=w, gravity=down)
        if r.ok:
            pool.split[i] = np.array([r.joint_angles_deg[a] for a in SPLIT_ANGLES])
        ref = w if view.baseline_world is None else view.baseline_world[i]
        if not r.ok or ref is None or lm is None:
            continue
        est_w = ref[BODY12_IDX, :3]
        if not np.isfinite(est_w).all():
            continue
        pool.answered += 1
        truth = view.truth_cam[i]
        joints = O.fitted_joints(r)
        pool.fit.add(joints, truth)
        pool.world.add(est_w, truth)
        pool.flat.add(np.column_stack([lm[BODY12_IDX, :2], np.zeros(12)]), truth)
        hip_z = _mid_hip(truth)[2]
        for source, z in (("true", truth[:, 2]), ("world", hip_z + est_w[:, 2] - _mid_hip(est_w)[2]),
                          ("fit", hip_z + joints[:, 2] - _mid_hip(joints)[2])):
            pool.depth_from[source].add(_back_project(lm[BODY12_IDX, :2], z, k), truth)
        root = O.root_cam(r)
        if root is not None:
            pool.root_err.append(float(np.linalg.norm(root - _mid_hip(truth))) * 1e3)
            pool.roots[i] = view.camera.to_world(root)


def _back_project(uv: np.ndarray, z: np.ndarray, k: Intrinsics) -> np.ndarray:
    """Pixels ``uv`` (n, 2) at depths ``z`` (n,) metres -> camera-frame points (n, 3)."""
    return np.column_stack([(uv[:, 0] - k.cx) * z / k.fx, (uv[:, 1] - k.cy) * z / k.fy, z])


def run(shared_data: Path, base: FitConfig | None = None, cache: Path | None = None) -> list[dict]:
    """One row per (view, mode, fps) and one row per (mode, fps) over the four views (see the module
    docstring)."""
    from posed.daemon.preflight import cache_dir

    base = base or FitConfig()
    folder = shared_data / DATA
    cameras = load_cameras(folder)
    truth = load_truth(folder)
    cache = cache or cache_dir() / "bench" / PROTOCOL

    def views(step: int) -> dict[str, list[_View]]:
        """Per camera, one view per starting frame 0 .. step - 1."""
        video = {n: folder / "balancing" / f"{n}.mp4" for n in CAMERAS}
        return {n: [_load_view(cameras[n], landmark_recording(video[n], cache, step=step, phase=p), truth,
                               landmark_recording(video[n], cache, mediapipe_sides=True, step=step, phase=p))
                    for p in range(step)]
                for n in CAMERAS}

    per_step = {step: views(step) for step in sorted({round(VIDEO_FPS / fps) for _, fps in RUNS})}
    Fitter(base).warmup()
    rows = []
    for mode, fps in RUNS:
        per_view = {n: _fit_view(v, mode, fps, base) for n, v in per_step[round(VIDEO_FPS / fps)].items()}
        for n, res in per_view.items():
            rows.append({"protocol": PROTOCOL, "domain": DOMAIN, "view": n, "mode": mode, "fps": fps,
                         **{k: v for k, v in res.items() if not k.startswith("_")}})
        rows.append(_overall(per_view, mode, fps))
        if (mode, fps) == GRAVITY_RUN:
            with_g = {n: _fit_view(v, mode, fps, base, gravity=True) for n, v in per_step[round(VIDEO_FPS / fps)].items()}
            rows.append({**_overall(with_g, mode, fps), "gravity": "calibration"})
        if (mode, fps) == EXTERNAL_RUN:
            step = round(VIDEO_FPS / fps)
            rows[-1]["external_recordings"] = _external(
                {n: [_load_view(cameras[n], landmark_recording(folder / "balancing" / f"{n}.mp4", cache,
                                                               mediapipe_sides=True, step=step, phase=p), truth)
                     for p in range(step)] for n in CAMERAS}, mode, step, base)
    return rows


def _external(runs: dict[str, list[_View]], mode: str, step: int, base: FitConfig) -> dict:
    """What ``posed fit`` makes of recordings another extractor wrote (here the landmark stage with
    MediaPipe's own left/right labels, ``landmarks.keep_sides=false``): PA-MPJPE (mm, every answered frame of
    every view) with the labels as they come and with the check ``posed fit`` runs on such a recording
    (landmarks.sides), and on how many frames it put them back."""
    from posed.landmarks import SideKeeper

    scores = {"as_they_come": _Scores(), "sides_put_back": _Scores()}
    swapped = 0
    for views in runs.values():
        for phase, view in enumerate(views):
            k = view.camera.intrinsics(view.image_size)
            for key, score in scores.items():
                fitter, keeper = Fitter(base), SideKeeper()
                for i in range(phase, len(view.landmarks), step):
                    lm, w = view.landmarks[i], view.world[i]
                    if lm is None:
                        keeper.reset()
                        continue
                    if key == "sides_put_back":
                        lm, w, s = keeper.check(i / VIDEO_FPS, lm, w)
                        swapped += s
                    r = fitter.fit(lm, i, i / VIDEO_FPS, view.image_size, mode=mode, intrinsics=k, world=w)
                    if r.ok:
                        score.add(O.fitted_joints(r), view.truth_cam[i])
    return {"fit_pa_mpjpe_mm": {k: s.summary()["pa_mpjpe_mm"] for k, s in scores.items()},
            "frames": {k: len(s.pa) for k, s in scores.items()}, "frames_put_back": swapped}


def _overall(per_view: dict[str, dict], mode: str, fps: float) -> dict:
    """The four views together: frame-weighted means, and the spread of the four views' mid-hip positions in
    the world (mm, median over frames every view answered)."""
    def mean(key: str, sub: str) -> float | None:
        vals = [(r[sub][key], r["answered"]) for r in per_view.values() if r[sub].get(key) is not None]
        n = sum(w for _, w in vals)
        return round(sum(v * w for v, w in vals) / n, 3 if key == "depth_flips" else 1) if n else None

    common = set.intersection(*(set(r["_roots"]) for r in per_view.values()))
    spread = [float(np.mean(np.linalg.norm(np.stack([r["_roots"][i] for r in per_view.values()]) -
                                           np.mean([r["_roots"][i] for r in per_view.values()], axis=0), axis=1)))
              * 1e3 for i in sorted(common)]
    # the pelvis / hip / lumbar split is not observable: the views agree on it only if they share one "down"
    shared = set.intersection(*(set(r["_split"]) for r in per_view.values()))
    split_spread = {a: round(float(np.mean([np.std([r["_split"][i][j] for r in per_view.values()])
                                            for i in sorted(shared)])), 1) if shared else None
                    for j, a in enumerate(SPLIT_ANGLES)}
    keys = ("pa_mpjpe_mm", "mpjpe_hip_aligned_mm", "angle_err_deg", "depth_flips")
    frames = sum(r["frames"] for r in per_view.values())
    answered = sum(r["answered"] for r in per_view.values())
    roots = [r["root_err_mm"] for r in per_view.values() if r["root_err_mm"] is not None]
    fit = {k: mean(k, "fit") for k in keys}
    world = {k: mean(k, "blazepose_world") for k in keys}
    for who, out in (("fit", fit), ("blazepose_world", world)):
        rows = [(r[who]["per_angle_deg"], r["answered"]) for r in per_view.values() if r[who].get("per_angle_deg")]
        n = sum(w for _, w in rows)
        if n:
            out["per_angle_deg"] = {a: {s: round(sum(p[a][s] * w for p, w in rows) / n, 1) for s in ("abs", "signed")}
                                    for a in O.ANGLE_NAMES}
    return {"protocol": PROTOCOL, "domain": DOMAIN, "view": "all", "mode": mode, "fps": fps, "frames": frames,
            "answered": answered, "fit": fit, "blazepose_world": world,
            "flat_2d": {"pa_mpjpe_mm": mean("pa_mpjpe_mm", "flat_2d")},
            "depth_sources": {s: mean(s, "depth_sources") for s in ("true", "world", "fit")},
            "fit_over_blazepose_pa": round(fit["pa_mpjpe_mm"] / world["pa_mpjpe_mm"], 3)
            if fit["pa_mpjpe_mm"] and world["pa_mpjpe_mm"] else None,
            "root_err_mm": round(float(np.median(roots)), 1) if roots else None,
            "views_root_spread_mm": round(float(np.median(spread)), 1) if spread else None,
            "views_split_spread_deg": split_spread}


def markdown(rows: list[dict]) -> list[str]:
    """The four-view rows as a Markdown table (docs/bench/fit.md)."""
    out = ["| mode | fps | answered | PA-MPJPE mm fit / BlazePose world (ratio) / 2D flat | hip-aligned MPJPE mm "
           "fit / world | angle err deg fit / world | depth flips fit / world | root err mm | views' root spread mm |",
           "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        if r["view"] != "all":
            continue
        f, w = r["fit"], r["blazepose_world"]
        out.append(f"| {r['mode']}{' + gravity' if r.get('gravity') else ''} | {r['fps']:g} | {r['answered']}/{r['frames']} | {f['pa_mpjpe_mm']} / "
                   f"{w['pa_mpjpe_mm']} ({r['fit_over_blazepose_pa']}) / {r['flat_2d']['pa_mpjpe_mm']} | "
                   f"{f['mpjpe_hip_aligned_mm']} / {w['mpjpe_hip_aligned_mm']} | {f['angle_err_deg']} / "
                   f"{w['angle_err_deg']} | {f['depth_flips']} / {w['depth_flips']} | {r['root_err_mm']} | "
                   f"{r['views_root_spread_mm']} |")
    return out


def per_angle_markdown(rows: list[dict]) -> list[str]:
    """Each angle's error over the four views, one column per four-view row (``per_angle_deg``: mean absolute /
    mean signed, estimate - truth, degrees; the fit, then BlazePose's world landmarks)."""
    overall = [r for r in rows if r["view"] == "all" and r["fit"].get("per_angle_deg")]
    heads = [f"{r['mode']}{' + gravity' if r.get('gravity') else ''} {r['fps']:g} fps" for r in overall]
    out = ["| angle: abs / signed deg, fit; BlazePose world | " + " | ".join(heads) + " |",
           "|---|" + "---|" * len(overall)]
    for a in O.ANGLE_NAMES:
        cells = []
        for r in overall:
            f, w = r["fit"]["per_angle_deg"][a], r["blazepose_world"]["per_angle_deg"][a]
            cells.append(f"{f['abs']} / {f['signed']:+}; {w['abs']} / {w['signed']:+}")
        out.append(f"| {a} | " + " | ".join(cells) + " |")
    return out


if __name__ == "__main__":        # a quick look: python -m posed.bench.balancing_video
    from posed.daemon.preflight import shared_data

    rows = run(shared_data())
    print("\n".join(markdown(rows) + [""] + per_angle_markdown(rows)))
    print(json.dumps([r for r in rows if r["view"] == "all"], indent=1))
