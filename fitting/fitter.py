"""The fit of one person per frame: 2D landmarks (33 x 5) -> the humanoid's 19 variables, 23 joint angles and
12 joints in 3D (interfaces.md section 2).

Image mode (every frame on its own, and the first frame of a video): uDEAS over the search box (paper
Table 1, or the wide box that also holds lying and fallen people) with restarts, the first ones searching
around the body orientations computed from the hips and shoulders (both depth mirrors); Levenberg-Marquardt
ranks analytic starts (limbs solved from their 2D landmarks) and the best distinct restart results by a few
iterations and refines the best to convergence, then each limb's depth mirror in turn; the unobservable
pelvis tilt is set by its prior; with noisy landmarks the best candidates are refined again under a
noise-weighted pose prior (ranked the same way without depth); the smallest loss wins.

Video mode: several hypotheses refined from this frame's landmarks — the previous frame's solution, each
limb's depth mirror of it, this frame's own analytic starts (and optionally the paper's uDEAS window) — under
a temporal prior in time units (degrees per second times the time since the previous frame) weighted by the
landmark noise, a few iterations each to rank them and the best refined to convergence, so time decides only
between what the landmarks cannot tell apart and no pose is held.
A frame whose 2D error jumps (fast motion, a lost track) is fitted again in image mode and the better result
kept. docs/body-model.md describes every step.

``Fitter.fit`` never raises on bad landmarks: it returns ``ok: false`` with a reason.
"""

from __future__ import annotations

import math
import time

import numpy as np

from posed.camera_model import Intrinsics
from posed.fitting import forward_kinematics as FK
from posed.fitting import jitcache, refine, udeas
from posed.fitting import layout as L
from posed.fitting import problem as P
from posed.fitting.analytic import analytic_start
from posed.fitting.assemble import assemble
from posed.fitting.body import BodyDimensions, dimensions_for
from posed.fitting.candidates import image_candidates, score_all, score_into
from posed.fitting.config import FitConfig
from posed.fitting.depth_rows import depth_fit_at
from posed.fitting.depth_term import DEPTH_RMS_K, SENSOR_DEPTH_CAMERA, SURFACE_M, DepthFit, usable
from posed.fitting.hypotheses import best_hypothesis, video_starts
from posed.fitting.kinematics import BODY_LANDMARKS
from posed.fitting.measured import Measured, measured_landmarks
from posed.fitting.projection import image_scale
from posed.fitting.proportions import DEPTH_MIN_WEIGHT, ProportionLearner, joint_points
from posed.fitting.result import FitResult
from posed.fitting.vertical import level_data, level_frame, reexpress
from posed.fitting.world_term import (
    SENSOR_WORLD,
    WORLD_WEIGHT,
    flexion_prior,
    flexion_rows,
    rotation_observable,
    world_depths,
    world_flexion,
    world_joints,
)

MODES = ("video", "image")
_TORSO = ("left_shoulder", "right_shoulder", "left_hip", "right_hip")
EXACT_MSE = 1e-14          # mean squared 2D error (body heights^2) of an exact fit (1e-7 H rms)
STRAIGHT_RAD = math.radians(5.0)  # a limb bent less than this has an exact depth mirror
PRIOR_MIN_NOISE = 0.001  # below this estimated landmark noise (fraction of body height) no prior is used
MIRROR_PASSES = 2  # image mode: passes over the four limb mirrors (a second one only after an improvement)
PRIOR_CANDIDATES = 4  # image mode, noisy landmarks: refine this many of the best candidates again with the prior
RECOVER_FACTOR, RECOVER_FLOOR, ERR_REF_RATE = 1.25, 0.002, 0.1  # video mode: when to look again in image mode
DEPTH_WEIGHT = 10.0  # a landmark's depth contradicting a hypothesis costs this many landmark-noise units
TRIAL_ITERATIONS = 5  # LM iterations that rank image mode's candidates and (without depth) its refinements
                      # under the pose prior, and that move the previous solution to a video frame ...
HYPOTHESIS_ITERATIONS = 3  # ... that rank video mode's hypotheses under the temporal prior (5 gave the same
                           # accuracy on the out-of-domain protocol, within 0.8 mm per row, in a fifth more time) ...
FINALISTS = 2  # ... and how many of the best are then refined to convergence
_NO_DEPTH = np.full(L.N_LM, np.nan)  # the depth kernels' "no measured depth"
_NO_SEEDS = np.zeros((0, L.N_VAR))  # no orientation seeds (read-only use: uDEAS starts, analytic starts)
MIN_DT_S = 1.0 / 120.0  # video mode: the temporal prior never assumes frames closer than this (a repeated stamp)


class Fitter:
    """Fits frames of one person; keeps the previous frame's solution for video mode."""

    def __init__(self, config: FitConfig | None = None, dims: BodyDimensions | None = None) -> None:
        """``dims``: the body to fit instead of the configured one (body height or calibration file); like a
        calibration, nothing is learned over it."""
        jitcache.ensure_fresh()  # before any kernel is loaded from numba's cache (once per process)
        self.config = config or FitConfig()
        # a bad calibration file raises CalibrationError here (a configuration error, not a frame error)
        self.base_dims: BodyDimensions = (dims if dims is not None else
                                          dimensions_for(self.config.body_height_m, self.config.calibration))
        self.dims: BodyDimensions = self.base_dims  # the lengths of the current fit (learned ones in video mode)
        # video mode without a calibration file: the person's own proportions, learned from the frames
        self._learner = (ProportionLearner(self.base_dims) if self.config.learn_proportions
                         and not self.config.calibration and dims is None else None)
        self._learn_t: float | None = None  # time of the last frame the learner saw
        self._work = FK.empty_work()
        self._fixed_deg = np.zeros(L.N_FIXED)  # the joint angles that are not estimated (fitting.reported.FIXED_NAMES), degrees
        self._rotation = (False, False)   # this frame searches the (left, right) upper arm's rotation
        self._depth: np.ndarray | None = None  # this frame's measured depth at the 12 body landmarks, metres
        self._sensor = SENSOR_DEPTH_CAMERA       # ... of this sensor: a depth camera, or the world landmarks
        self._depth_weight = DEPTH_WEIGHT        # ... and its weight against the 2D landmarks
        self._world: np.ndarray | None = None    # this frame's world landmarks (33 x 5), when given
        self._level: np.ndarray | None = None    # the level frame R_CL the body angles are taken against
        self.reset()

    # --- state ---

    def reset(self) -> None:
        """Forget the previous frame (the next fit runs in image mode)."""
        self._prev_x: np.ndarray | None = None
        self._prev_ppm: float = 0.0
        self._prev_t: float | None = None
        self._err_ref: float = 0.0  # recent 2D error level in video mode (body heights)
        self._udeas_s: float = 0.0  # CPU time of the uDEAS kernel in the current fit

    def forget_body(self) -> None:
        """Forget the learned proportions (another person). A lost track (``reset``) keeps them; so does a
        while without anybody (``proportions_forget_s`` without a fitted video frame), but only as the prior
        that new samples start from (fitting.proportions ``ProportionLearner.retain``); time going back (another
        recording) forgets them."""
        if self._learner is not None:
            self._learner.forget()
        self._learn_t = None

    def warmup(self) -> None:
        """Compile (or load from the numba cache) every kernel by fitting a simulated frame in both modes."""
        from posed.fitting.warmup import warmup_depth, warmup_landmarks

        lm = warmup_landmarks(self.dims)
        noisy = warmup_landmarks(self.dims, noise_px=3.0, seed=1)
        saved = (self._prev_x, self._prev_ppm, self._prev_t, self._err_ref)
        learner, self._learner = self._learner, None   # the simulated frames teach nothing about the person
        self.reset()
        self.fit(lm, 0, 0.0, (640, 480), mode="image")
        self.fit(lm, 1, 1 / 30, (640, 480), mode="video")
        self.fit(noisy, 2, 2 / 30, (640, 480), mode="video")      # the prior paths (noise > 0)
        k = Intrinsics(600.0, 600.0, 320.0, 240.0, 640, 480)
        depth = warmup_depth(self.dims)   # the depth term's kernels, called from Python and from kernels
        self.fit(noisy, 3, 3 / 30, (640, 480), mode="image", intrinsics=k, depth_m=depth)
        self.fit(noisy, 4, 4 / 30, (640, 480), mode="video", intrinsics=k, depth_m=depth)
        # the proportion learner's kernel (the learner is off above): any frame, one signature
        xy, w, _ = P.landmark_weights(lm, self.config)
        image_scale(np.ones(L.N_VAR), P.pack(xy, w, self.dims, self.config, P.reference_scale(xy, w, self.dims)).data)
        self._prev_x, self._prev_ppm, self._prev_t, self._err_ref = saved
        self._learner = learner

    # --- the fit ---

    def fit(self, landmarks: np.ndarray | None, seq: int, t: float, image_size: tuple[int, int],
            mode: str = "video", intrinsics: Intrinsics | None = None,
            depth_m: np.ndarray | None = None, world: np.ndarray | None = None,
            gravity=None) -> FitResult:
        """Fit one frame. ``landmarks``: (33, 5) ``[x_px, y_px, z, visibility, presence]`` or None (no person).

        ``intrinsics``: the camera's, in pixels of the landmarks' image, or None (unknown: with ``projection``
        auto the fit is orthographic); an assumed lens (``Intrinsics.assume``, what the daemon gives a source
        without intrinsics) is projected through like the camera's own, but no ``root_cam_m`` comes of it
        (the result's ``lens``: given or assumed). ``depth_m``: what
        an aligned depth camera measured at each of the 33 landmarks, metres along the camera's z axis, NaN
        where unknown (interfaces.md section 1), or None: used by a robust term (fitting.depth_term) and for
        ``root_cam_m``. ``world``: BlazePose's world landmarks of the frame (33 x 5, metres, hip-centred;
        interfaces.md section 1), or None: without depth, the same robust term's evidence of each limb's depth
        (fitting.world_term; ``world_landmarks`` in the config). ``gravity``: the direction of gravity (down)
        in the camera's axes, any length (an IMU's, or a measured mount's tilt and roll), or None: the camera
        is taken as level. With it the pelvis-tilt prior and the centre of mass over the feet measure against
        the true vertical (fitting.vertical); the result's ``vertical`` says which one the fit used.
        """
        t0 = time.perf_counter()
        self._depth = None
        self._world = None
        try:
            try:
                level = level_frame(gravity if self.config.vertical == "auto" else None)
            except ValueError as exc:
                return FitResult.failure(seq, float(t) if _finite(t) else 0.0, str(exc))
            if self._prev_x is not None:
                self._prev_x = reexpress(self._prev_x, self._level, level)   # the same body, maybe a new down
            self._level = level
            if world is not None and self.config.world_landmarks:
                wl = np.asarray(world, dtype=np.float64)
                if wl.shape != (33, 5):
                    return FitResult.failure(seq, float(t) if _finite(t) else 0.0,
                                             f"world must be 33 x [x, y, z, visibility, presence], got shape "
                                             f"{wl.shape}")
                self._world = wl
            if depth_m is not None:
                d = np.asarray(depth_m, dtype=np.float64)
                if d.shape != (33,):
                    return FitResult.failure(seq, float(t) if _finite(t) else 0.0,
                                             f"depth_m must be 33 values (metres or NaN), got shape {d.shape}")
                self._depth = d[list(BODY_LANDMARKS)]
            return self._fit(landmarks, seq, t, image_size, mode, intrinsics, t0)
        except Exception as exc:  # never raise on bad input: report it
            self.reset()
            return FitResult.failure(seq, float(t) if _finite(t) else 0.0,
                                     f"fit failed: {type(exc).__name__}: {exc}")

    def _fit(self, landmarks, seq, t, image_size, mode, intrinsics, t0) -> FitResult:
        cfg = self.config
        t = float(t) if _finite(t) else 0.0
        if mode not in MODES:
            return FitResult.failure(seq, t, f"mode {mode!r} is not one of: video, image")
        if landmarks is None:
            self.reset()
            return FitResult.failure(seq, t, "no person")
        lm = np.asarray(landmarks, dtype=np.float64)
        if lm.shape != (33, 5):
            self.reset()
            return FitResult.failure(seq, t, f"landmarks must be a (33, 5) array, got shape {lm.shape}")
        try:
            width, height = (int(v) for v in image_size)
        except (TypeError, ValueError):
            return FitResult.failure(seq, t, f"image_size must be (width, height), got {image_size!r}")
        if width <= 0 or height <= 0:
            return FitResult.failure(seq, t, f"image_size must be positive, got {image_size!r}")
        self.dims = self._dims_for(mode, t)
        xy, w, missing = P.landmark_weights(lm, cfg)
        usable = 12 - len(missing)
        torso_missing = [n for n in _TORSO if n in missing]
        if usable < cfg.min_landmarks or len(torso_missing) > 1:
            self.reset()
            return FitResult.failure(
                seq, t, f"too few usable body landmarks ({usable} of 12, need {cfg.min_landmarks} with at least "
                        f"3 of the shoulders and hips); missing or visibility < {cfg.visibility_drop}: "
                        + ", ".join(missing), missing=missing)
        ppm0 = P.reference_scale(xy, w, self.dims)
        if not ppm0 > 0:
            self.reset()
            return FitResult.failure(seq, t, "the body landmarks collapse to a point; no scale can be measured",
                                     missing=missing)
        if intrinsics is not None and not isinstance(intrinsics, Intrinsics):
            self.reset()
            return FitResult.failure(seq, t, f"intrinsics must be a camera_model.Intrinsics or None, got "
                                             f"{intrinsics!r}")
        use_persp = cfg.projection == "perspective" or (cfg.projection == "auto" and intrinsics is not None)
        if use_persp and intrinsics is None:
            return FitResult.failure(seq, t, "projection is 'perspective' but no camera intrinsics were given "
                                             "(add \"camera\" to the recording header or use projection: auto)")
        lens_assumed = use_persp and intrinsics.assumed   # a lens taken for granted: no metres from it
        # the depth evidence: a depth camera's, else the world landmarks' (fitting.world_term)
        self._sensor, self._depth_weight = SENSOR_DEPTH_CAMERA, DEPTH_WEIGHT
        if self._depth is None and self._world is not None:
            self._depth = world_depths(self._world, self.dims, cfg.visibility_drop)
            self._sensor, self._depth_weight = SENSOR_WORLD, WORLD_WEIGHT
        camera_depth = self._sensor is SENSOR_DEPTH_CAMERA
        # the upper arms' rotations are searched where the world landmarks tell the arms' depth, else held at 0
        self._rotation = (rotation_observable(self._world, self.dims, cfg.visibility_drop)
                          if cfg.shoulder_rotation and not camera_depth and self._depth is not None
                          else (False, False))
        frame = P.pack(xy, w, self.dims, cfg, ppm0, intrinsics if use_persp else None, self._fixed_deg,
                       self._rotation, level_data(self._level))
        video_ok = (mode == "video" and self._prev_x is not None and self._prev_t is not None
                    and 0.0 <= t - self._prev_t <= cfg.video_max_gap_s)

        self._udeas_s = 0.0
        x, loss, mp, evals, used_mode = self._solve(frame, video_ok, ppm0, t)
        if any(self._rotation) and self._depth is None:
            # the world landmarks were judged garbage (no hypothesis agrees with their depths: the tracker on
            # another body): nothing tells the arms' rotations either -- the frame is solved again without them
            self._rotation = (False, False)
            frame = P.pack(xy, w, self.dims, cfg, ppm0, intrinsics if use_persp else None, self._fixed_deg,
                           level=level_data(self._level))
            x, loss, mp, more, used_mode = self._solve(frame, video_ok, ppm0, t)
            evals += more
        if used_mode == "image":
            self._err_ref = mp
        else:
            self._err_ref += ERR_REF_RATE * (mp - self._err_ref)
        fit_ms = (time.perf_counter() - t0) * 1000.0
        gamma = float(x[0] * ppm0 * self.dims.body_height_m / height)
        if not mp <= cfg.max_error or not gamma <= cfg.max_gamma:
            self.reset()
            what = (f"mean 2D error {mp:.3f} of body height exceeds max_error {cfg.max_error}"
                    if not mp <= cfg.max_error else
                    f"the body would be {gamma:.1f} image heights tall (max_gamma {cfg.max_gamma})")
            return FitResult.failure(seq, t, f"fit rejected: {what}; the landmarks do not fit a person",
                                     loss=float(loss), fit_ms=fit_ms)
        self._prev_x, self._prev_ppm, self._prev_t = x.copy(), ppm0, t
        # root_cam_m and the learned lengths take a depth camera's metres only (the world depths are relative)
        depth = self._depth_fit(frame, x) if camera_depth else None
        result = assemble(seq, t, x, frame, self._fixed_deg, loss=loss, mp=mp, fit_ms=fit_ms, mode=used_mode,
                          evals=evals, udeas_s=self._udeas_s, missing=missing, gamma=gamma, depth=depth,
                          measured=Measured.from_landmarks(measured_landmarks(lm, cfg.visibility_drop)),
                          rotation=self._rotation, lens_assumed=lens_assumed, level=self._level)
        # what the fit used: the 2D landmarks always; a depth camera's or the world landmarks' depths when they
        # were given and not judged garbage (fitting.depth_term.usable)
        evidence = ["landmarks"]
        if self._depth is not None:
            evidence.append("depth" if camera_depth else "world")
            if not camera_depth:
                world_fit = self._depth_fit(frame, x)
                result.extra["world_inliers"] = 0 if world_fit is None else world_fit.inliers
        result.extra["evidence"] = evidence
        if mode == "video" and self._learner is not None:
            result.extra["limb_scale"] = self._learner.scale.to_json()  # the lengths this fit used
            obs = frame.data[L.D_OBS:L.D_OBS + 2 * L.N_LM].reshape(L.N_LM, 2)
            pts, sd = None, 0.0
            if depth is not None and use_persp and not lens_assumed:   # lengths in 3D: depth-consistent landmarks
                use = (depth.weights >= DEPTH_MIN_WEIGHT) & (frame.weights > 0)
                pts = joint_points(xy, self._depth, use, SURFACE_M, intrinsics)
                sd = DEPTH_RMS_K * depth.root_z ** 2   # the camera's noise at the person's distance
            # the world landmarks' 3D joints give lengths too, where the fit used them (not judged garbage)
            world = None if camera_depth or self._depth is None else world_joints(self._world, cfg.visibility_drop)
            self._learner.observe(obs, frame.weights, image_scale(x, frame.data), self.dims, pts, sd, world)
            self._learn_t = t
        return result

    @property
    def _lim(self) -> tuple[np.ndarray, np.ndarray]:
        """This frame's joint limits (fitting.problem.limits)."""
        return P.limits(self._rotation)

    def _solve(self, frame: P.Frame, video: bool, ppm0: float, t: float) -> tuple[np.ndarray, float, float, int, str]:
        """(x, loss, 2D error, evaluations, mode used) of one packed frame: video mode from the previous
        solution when ``video``, falling back to image mode when the 2D error jumps; else image mode."""
        cfg = self.config
        if video:
            prev = self._prev_x.copy()
            prev[0] *= self._prev_ppm / ppm0  # same pixel scale under the new reference
            x, loss, mp, evals = self._video(frame, prev, t - self._prev_t)
            # lost track (fast motion, a wrong branch after an ambiguity): the 2D error jumps above its
            # recent level -> fit this frame in image mode too and keep the better of the two
            if mp > min(cfg.video_recover_error, RECOVER_FACTOR * self._err_ref + RECOVER_FLOOR):
                xi, li, mi, ei = self._image(frame)
                if li < loss:
                    return xi, li, mi, evals + ei, "video+image"
                return x, loss, mp, evals + ei, "video"
            return x, loss, mp, evals, "video"
        x, loss, mp, evals = self._image(frame)
        return x, loss, mp, evals, "image"

    def _dims_for(self, mode: str, t: float) -> BodyDimensions:
        """The lengths to fit this frame with: the learned ones in video mode, else the configured ones."""
        if mode != "video" or self._learner is None:
            return self.base_dims
        if self._learn_t is not None and t < self._learn_t:
            self.forget_body()   # time went back: another recording
        elif self._learn_t is not None and t - self._learn_t > self.config.proportions_forget_s:
            self._learner.retain()   # a while without anybody: the same person may come back, or someone else
            self._learn_t = None
        return self._learner.dims()

    def _lm(self, data: np.ndarray, x: np.ndarray, iterations: int | None = None) -> tuple[np.ndarray, float]:
        """Levenberg-Marquardt from ``x`` on ``data``: (solution, its cost); ``iterations`` at most (default
        ``refine_iterations``)."""
        out = np.empty(L.N_VAR)
        n = self.config.refine_iterations if iterations is None else iterations
        cost = refine.levenberg_marquardt(x, *self._lim, data, n, out)[0]
        return out, float(cost)

    def _score(self, frame: P.Frame, x: np.ndarray) -> tuple[np.ndarray, float, float]:
        """Set the pelvis tilt by its prior and evaluate the loss: (x, loss, mpjpe)."""
        out = np.empty(L.N_VAR)
        loss, mp = score_into(x, frame.data, *self._lim, self._work, out)
        return out, float(loss), float(mp)

    def _score_all(self, frame: P.Frame, pool: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`_score` of each row of ``pool``: (xs, losses, mpjpes)."""
        scored, loss, mp = np.empty_like(pool), np.empty(len(pool)), np.empty(len(pool))
        score_all(pool, len(pool), frame.data, *self._lim, self._work, scored, loss, mp)
        return scored, loss, mp

    def _select(self, frame: P.Frame, pool: np.ndarray, mse: np.ndarray,
                scored: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None) -> tuple[np.ndarray, float, float]:
        """The best of refined candidates.

        Noise-free (an exact fit): the smallest loss. With landmark noise the depth of limbs near the image
        plane is weakly determined, so the best candidates are refined again with a pose prior weighted by
        the noise estimated from the best residual (MAP; zero for an exact fit): left/right symmetry and a
        straight spine (``pose_prior``). It decides between depth hypotheses that fit the landmarks alike.
        The smallest prior-weighted cost wins. (Video mode's temporal prior: :meth:`_track`.) Each of the
        PRIOR_CANDIDATES best gets TRIAL_ITERATIONS Levenberg-Marquardt iterations under the prior, enough to
        rank them, and the FINALISTS best are refined to convergence.

        ``pool``: the candidates (n x 19); ``mse``: ``refine.data_mse`` of each; ``scored``: :meth:`_score_all`
        of the pool when the caller already has it.

        With measured depth at the landmarks (``self._depth``) every comparison also counts the robust depth
        term (fitting.depth_term), weighted so that a landmark whose depth contradicts a hypothesis costs as
        much as DEPTH_WEIGHT times the landmark noise: it decides between hypotheses the 2D landmarks cannot
        tell apart (a limb towards or away from the camera) and never outweighs a clearly better 2D fit; each
        of the PRIOR_CANDIDATES best is then refined to convergence in two passes, the depth rows'
        robust weights re-solved from the previous pass's result (ranking by a few iterations lost accuracy
        there: 0.7-0.9 mm PA-MPJPE on the out-of-domain protocol).
        """
        cfg = self.config
        xs, loss, mp = self._score_all(frame, pool) if scored is None else scored
        f_min = float(mse.min())
        # landmark noise variance per coordinate from the residual (3 degrees of freedom: 24 coordinates,
        # 19 variables, 2 translations), capped: a poor fit is a model mismatch rather than noise
        sigma2 = min(4.0 * f_min, cfg.pose_prior_max_noise ** 2)
        noise2 = max(sigma2, PRIOR_MIN_NOISE ** 2)
        total = loss
        if self._depth is not None:
            fits = [self._depth_fit(frame, x) for x in xs]
            if any(usable(d, self._depth) for d in fits):
                # the 2D loss is a mean distance (normalized units), the refinement's cost a sum of squares
                total = loss + self._depth_weight * math.sqrt(noise2) * np.array(
                    [0.0 if d is None else d.cost for d in fits])
            else:
                self._depth = None  # no hypothesis agrees with most of the measured depths: garbage, not used
        b = int(np.argmin(total))   # the first of equal ones
        best = xs[b], float(loss[b]), float(mp[b])
        if not (cfg.refine and cfg.pose_prior > 0):
            return best
        if sigma2 < PRIOR_MIN_NOISE ** 2:
            return best  # (nearly) exact: no noise to regularize
        data = P.with_prior(frame, cfg.pose_prior * sigma2 / 12.0, P.PRIOR_MU_RAD, P.PRIOR_SIG_RAD, P.PRIOR_PARTNER)
        if self._depth is not None and self._sensor is SENSOR_WORLD:
            # the world landmarks (judged usable above) measure the knees' and elbows' flexion too
            flexion_rows(data, world_flexion(self._world, cfg.visibility_drop), sigma2 / 12.0, best[0])
        order = np.argsort(total)
        best_x = np.empty(L.N_VAR)
        starts = pool[order[:PRIOR_CANDIDATES]]
        if self._depth is None:  # no depth rows: the refinement's cost is the compared one
            best_hypothesis(starts, *self._lim, data, _NO_DEPTH, self._sensor, False, 0.0,
                            min(TRIAL_ITERATIONS, cfg.refine_iterations), cfg.refine_iterations, FINALISTS, best_x)
        else:
            # with depth: each converged in two passes, the depth rows' robust weights solved from its start and
            # again from the first pass's result (the kernel's trial and its finalist refinement, every start a
            # finalist); compared on the cost without those rows plus the depth term
            best_hypothesis(starts, *self._lim, data, self._depth, self._sensor, True,
                            self._depth_weight * noise2,
                            cfg.refine_iterations, cfg.refine_iterations, len(starts), best_x)
        return self._score(frame, best_x)

    def _track(self, frame: P.Frame, prev: np.ndarray, dt: float, hypotheses: np.ndarray,
               sigma2: float) -> tuple[np.ndarray, float, float]:
        """Video mode with landmark noise: the hypotheses refined under the temporal prior, the smallest
        prior-weighted cost wins (MAP over the hypotheses).

        The prior is the previous frame's solution ``prev`` in time units: each angle may move
        ``video_joint_speed_deg_s`` x ``dt`` at one standard deviation, so it does not depend on the frame
        rate; weighted by the landmark noise variance ``sigma2`` (estimated from the residual of the previous
        solution refined on this frame; ``video_smoothing``), it decides only between hypotheses the
        landmarks cannot tell apart. Every hypothesis gets HYPOTHESIS_ITERATIONS Levenberg-Marquardt iterations,
        enough to rank them; the FINALISTS best are refined to convergence. With measured depth each
        refinement also carries the depth rows (robust weights from its start, re-solved from the trial's
        result for the finalists), unless no hypothesis agrees with the depth (garbage: the frame is fitted
        without it). World landmarks that are used also measure the knees' and elbows' flexion, folded into the
        prior (fitting.world_term.flexion_prior)."""
        cfg = self.config
        sig = np.full(L.N_VAR, math.radians(cfg.video_joint_speed_deg_s * max(dt, MIN_DT_S)))
        sig[0] = 0.0
        if self._depth is not None and not any(usable(self._depth_fit(frame, x), self._depth) for x in hypotheses):
            self._depth = None  # no hypothesis agrees with most of the measured depths: garbage, not used
        mu = prev
        if self._depth is not None and self._sensor is SENSOR_WORLD:
            # the world landmarks (judged usable just above) measure the knees' and elbows' flexion too
            mu = prev.copy()
            flexion_prior(mu, sig, world_flexion(self._world, cfg.visibility_drop))
        data = P.with_prior(frame, cfg.video_smoothing * sigma2 / 12.0, mu, sig, -1.0)
        w_depth = self._depth_weight * sigma2

        best_x = np.empty(L.N_VAR)
        use_depth = self._depth is not None
        best_hypothesis(hypotheses, *self._lim, data, self._depth if use_depth else _NO_DEPTH,
                        self._sensor, use_depth, w_depth, min(HYPOTHESIS_ITERATIONS, cfg.refine_iterations), cfg.refine_iterations,
                        FINALISTS, best_x)
        return self._score(frame, best_x)

    def _depth_fit(self, frame: P.Frame, x: np.ndarray) -> DepthFit | None:
        """The depth term of solution ``x`` against this frame's measured depth (None without depth)."""
        return None if self._depth is None else depth_fit_at(x, frame.data, self._depth, self._sensor)

    def _analytic(self, frame: P.Frame, seeds: np.ndarray) -> list[np.ndarray]:
        """Starting points from the orientation seeds with every limb solved from its 2D landmarks (each
        limb's depth sign chosen by the loss; fitting.analytic), for the refinement."""
        out = []
        for seed in seeds:
            x = np.empty(L.N_VAR)
            analytic_start(seed, frame.data, self._work, x)
            out.append(x)
        return out

    def _image(self, frame: P.Frame) -> tuple[np.ndarray, float, float, int]:
        """Image mode: uDEAS, then Levenberg-Marquardt from the analytic starts and the best distinct restart
        results. Each candidate gets TRIAL_ITERATIONS iterations, enough to rank them, and the FINALISTS best
        (by the refinement's cost) are refined to convergence, stopping at the first exact fit (a trial that
        is exact already is converged and ends the search). Then each limb's depth mirror of the best so far
        in turn, refined to convergence and kept when its loss is lower (MIRROR_PASSES passes; the mirrors of
        bent limbs are skipped after an exact fit); :meth:`_select` chooses among all of them, the trials not
        refined further included (under the pose prior they are starts like the others)."""
        cfg = self.config
        lo, hi = P.image_box(cfg, self._rotation)
        seeds = P.orientation_seeds(frame, self.dims, lo, hi) if cfg.seed_orientation else _NO_SEEDS
        seeds = seeds[: cfg.restarts]
        los, his = P.restart_boxes(lo, hi, seeds, cfg.restarts)
        c0 = time.thread_time()
        best_x, _, evals, rx, rc = udeas.minimize(udeas.PROBLEM_POSE, los, his, restarts=cfg.restarts,
                                                  m0=cfg.row_init, mf=cfg.row_max, seed=cfg.seed, data=frame.data,
                                                  work=self._work, x_init=seeds)
        self._udeas_s += time.thread_time() - c0
        if not cfg.refine:
            return (*self._score(frame, best_x), int(evals))
        # the best restart results that differ from each better one by more than 0.05 in some angle
        apart = (np.abs(rx[:, None, 1:] - rx[None, :, 1:]).max(axis=2) > 0.05).tolist()
        keep: list[int] = []
        for i in np.argsort(rc).tolist():
            if len(keep) >= cfg.refine_candidates:
                break
            if all(apart[i][j] for j in keep):
                keep.append(i)
        picked = [rx[i].copy() for i in keep]
        if cfg.analytic_seeds:
            picked = self._analytic(frame, seeds) + picked
        # every candidate ranked by a few iterations, the best refined to convergence (stop at an exact fit),
        # then each limb's depth mirror of the best so far in turn (two wrong limbs get fixed one by one)
        passes = MIRROR_PASSES if cfg.limb_mirrors else 0
        k = len(picked)
        pool = np.empty((k + 4 * passes, L.N_VAR))
        scored = np.empty_like(pool)
        loss, mp, mse = np.empty(len(pool)), np.empty(len(pool)), np.empty(len(pool))
        n = image_candidates(np.array(picked).reshape(k, L.N_VAR), *self._lim, frame.data,
                             self._work, min(TRIAL_ITERATIONS, cfg.refine_iterations), cfg.refine_iterations,
                             FINALISTS, passes, EXACT_MSE, STRAIGHT_RAD, pool, scored, loss, mp, mse)
        return (*self._select(frame, pool[:n], mse[:n], scored=(scored[:n], loss[:n], mp[:n])), int(evals))

    def _video(self, frame: P.Frame, prev: np.ndarray, dt: float) -> tuple[np.ndarray, float, float, int]:
        """Video mode: several hypotheses refined from this frame's landmarks, chosen by temporal consistency.

        Starts: the previous frame's solution; each limb's depth mirror of it (a limb pointing at the camera
        and one pointing away project alike, so a wrong depth choice is never carried forward); and this
        frame's own analytic starts (both depth mirrors of the body orientation from the hips and shoulders,
        every limb solved from its 2D landmarks), so a pose the landmarks have left is not held. With
        landmark noise (:meth:`_track`) each is refined under the previous solution as a prior in time units
        (``video_joint_speed_deg_s`` times ``dt``, weighted by the landmark noise), which decides between
        hypotheses the landmarks cannot tell apart; without (an exact fit) the smallest loss wins
        (:meth:`_select`). ``dt``: seconds since the previous frame."""
        cfg = self.config
        if not cfg.refine:
            return (*self._score(frame, prev), 0)
        # the previous solution moved to this frame's landmarks: a trial's iterations tell the noise level
        start = self._lm(frame.data, prev, min(TRIAL_ITERATIONS, cfg.refine_iterations))[0]
        mse_start = refine.data_mse(start, frame.data)
        sigma2 = min(4.0 * mse_start, cfg.pose_prior_max_noise ** 2)  # as _select estimates it
        tracked = cfg.pose_prior > 0 and sigma2 >= PRIOR_MIN_NOISE ** 2   # noise: _track, under the prior
        if not tracked:
            # (nearly) exact, or no prior: converged, so that an exact fit is kept as it is and the pool below
            # compares converged candidates
            start = self._lm(frame.data, start)[0]
            mse_start = refine.data_mse(start, frame.data)
            if mse_start < EXACT_MSE:
                return (*self._score(frame, start), 0)
        # the hypotheses: the start, each limb's depth mirror of it, this frame's analytic starts (and uDEAS's)
        seeds = (P.orientation_seeds(frame, self.dims, *P.image_box(cfg, self._rotation))
                 if cfg.video_hypotheses and cfg.seed_orientation and cfg.analytic_seeds else _NO_SEEDS)
        mirrors = 4 if cfg.video_hypotheses else 0
        hyps = np.empty((1 + mirrors + len(seeds) + (cfg.video_restarts > 0), L.N_VAR))
        video_starts(start, seeds, mirrors, frame.data, self._work, hyps)
        evals = 0
        if cfg.video_restarts > 0:  # the paper's search: uDEAS within +-video_window_deg of the previous solution
            lo, hi = P.video_box(prev, cfg, self._rotation)
            c0 = time.thread_time()
            best_x, _, evals = udeas.minimize(udeas.PROBLEM_POSE, lo, hi, restarts=cfg.video_restarts,
                                              m0=cfg.video_row_init, mf=cfg.video_row_max, seed=cfg.seed,
                                              data=frame.data, work=self._work, x_init=prev)[:3]
            self._udeas_s += time.thread_time() - c0
            hyps[-1] = best_x
        if tracked:
            return (*self._track(frame, prev, dt, hyps, sigma2), int(evals))
        pool = np.empty_like(hyps)
        mse = np.empty(len(hyps))
        pool[0], mse[0] = start, mse_start
        for i in range(1, len(hyps)):
            pool[i] = self._lm(frame.data, hyps[i])[0]
            mse[i] = refine.data_mse(pool[i], frame.data)
        return (*self._select(frame, pool, mse), int(evals))


def _finite(v) -> bool:
    try:
        return math.isfinite(float(v))
    except (TypeError, ValueError):
        return False


__all__ = ["BODY_LANDMARKS", "Fitter"]
