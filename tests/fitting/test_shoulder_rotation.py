"""The upper arms' rotation about their own axis (x[X_PSISH_*], beyond the paper's 19 variables): searched only
when ``fitting.shoulder_rotation`` is on (off by default) and world landmarks tell the arms' depth, held at 0
otherwise (the paper's arm: a held variable changes nothing else, not even uDEAS's random draws); hands clasped
before the chest get their elbows right only with it; reported as ``shoulder_rotation_deg``."""

from __future__ import annotations

import itertools
from dataclasses import replace

import numpy as np
import pytest

from posed.bench import simulate as S
from posed.fitting import BODY_LANDMARKS, FitConfig, Fitter
from posed.fitting import layout as L
from posed.fitting import problem as P
from posed.fitting.body import BodyDimensions
from posed.fitting.kinematics import Pose

DIMS = BodyDimensions.from_height(1.7)
SIZE = (640, 480)


def _clasped(yaw: float) -> Pose:
    """Squatting with the hands together before the chest: upper arms down and a little forward, turned in."""
    joints = {"theta_hp_l": 80.0, "theta_hp_r": 80.0, "theta_kn_l": 100.0, "theta_kn_r": 100.0,
              "theta_tr": 20.0, "theta_sh_l": 25.0, "theta_sh_r": 25.0, "phi_sh_l": -15.0, "phi_sh_r": -15.0,
              "theta_el_l": 85.0, "theta_el_r": 85.0}
    return Pose(joints, psi_bd=yaw, psi_sh_l=55.0, psi_sh_r=55.0)


def _scene(pose: Pose, seed: int):
    """(2D landmarks with 1 px noise, exact world landmarks, intrinsics) of ``pose`` 3 m from a level camera."""
    camera = S.LevelCamera(model="pinhole", distance_m=3.0, height_m=1.0)
    lm = S.render(pose, dims=DIMS, camera=camera, image_size=SIZE, noise_px=1.0, seed=seed)
    pts, _ = S._world_points(pose, DIMS, S.Placement(), camera.distance_m, camera.height_m)
    w = np.full((33, 5), np.nan)
    w[:, :3] = pts - 0.5 * (pts[23] + pts[24])
    w[list(BODY_LANDMARKS), 3:] = 1.0
    return lm, w, camera.intrinsics(SIZE)


def _fit(cfg, lm, k, world, mode):
    """One fit; video mode's is the second frame of the same landmarks (the video path proper)."""
    fitter = Fitter(cfg)
    first = fitter.fit(lm, 0, 0.0, SIZE, mode=mode, intrinsics=k, world=world)
    return first if mode == "image" else fitter.fit(lm, 1, 0.1, SIZE, mode=mode, intrinsics=k, world=world)


def test_the_rotations_are_held_at_zero_without_world_landmarks():
    lo, hi = P.limits(False)
    assert lo[L.X_PSISH_L] == hi[L.X_PSISH_L] == lo[L.X_PSISH_R] == hi[L.X_PSISH_R] == 0.0
    lo, hi = P.limits(True)
    assert np.degrees([lo[L.X_PSISH_L], hi[L.X_PSISH_L]]).round(6).tolist() == [-90.0, 70.0]
    for rotation in (False, True):
        box = P.image_box(FitConfig(), rotation)
        assert (box[1][L.X_PSISH_L] > box[0][L.X_PSISH_L]) == rotation
        prev = np.zeros(L.N_VAR)
        prev[0] = 1.0
        prev[L.X_PSISH_L] = np.radians(50.0)        # the previous frame had one; this one has no world
        vlo, vhi = P.video_box(prev, FitConfig(), rotation)
        assert (vlo[L.X_PSISH_L] == vhi[L.X_PSISH_L] == 0.0) != rotation
        assert np.all(vlo <= vhi)
    frame = P.pack(np.zeros((12, 2)), np.ones(12), DIMS, FitConfig(), 100.0)
    assert frame.data[L.D_LIM_LO + L.X_PSISH_R] == frame.data[L.D_LIM_HI + L.X_PSISH_R] == 0.0


def test_each_arm_is_free_or_held_on_its_own():
    """A (left, right) pair frees one arm's rotation and holds the other's at 0, in the limits, the image box
    and the video window (the previous frame's rotation of a held arm is not kept)."""
    prev = np.zeros(L.N_VAR)
    prev[0] = 1.0
    prev[[L.X_PSISH_L, L.X_PSISH_R]] = np.radians(40.0)
    for pair in ((True, False), (False, True)):
        for lo, hi in (P.limits(pair), P.image_box(FitConfig(), pair), P.video_box(prev, FitConfig(), pair)):
            free = [hi[x] > lo[x] for x in (L.X_PSISH_L, L.X_PSISH_R)]
            assert free == list(pair)
            held = L.X_PSISH_R if pair[0] else L.X_PSISH_L
            assert lo[held] == hi[held] == 0.0
    assert P.limits((True, True)) == P.limits(True) and P.limits((False, False)) == P.limits(False)


def _arm_world(flex_deg: float, side: str = "l") -> np.ndarray:
    """World landmarks with one arm hanging, its elbow flexed by ``flex_deg`` (forearm forward: -z)."""
    w = np.full((33, 5), np.nan)
    sh, el, wr = (11, 13, 15) if side == "l" else (12, 14, 16)
    f = np.radians(flex_deg)
    w[sh, :3] = (0.18, -0.5, 0.0)
    w[el, :3] = (0.18, -0.2, 0.0)
    w[wr, :3] = w[el, :3] + 0.25 * np.array([0.0, np.cos(f), -np.sin(f)])
    w[[sh, el, wr], 3:] = 1.0
    return w


def test_an_arm_rotation_is_searched_only_where_the_world_landmarks_can_tell_it():
    """Turning the upper arm by ROTATION_STEP_DEG moves the wrist by forearm * sin(flexion) * step: beyond the
    world landmarks' depth error only for an elbow flexed between about 54 and 126 degrees (a 1.70 m body's
    forearm); a straight or folded arm, or one with a hidden or unknown landmark, is held."""
    from posed.fitting.world_term import WORLD_SIGMA_M, rotation_observable

    edge = np.degrees(np.arcsin(WORLD_SIGMA_M / (DIMS.forearm_m * np.radians(30.0))))
    assert 50.0 < edge < 58.0
    for flex, want in ((5.0, False), (edge - 2, False), (edge + 2, True), (90.0, True), (180 - edge - 2, True),
                       (180 - edge + 2, False), (170.0, False)):
        assert rotation_observable(_arm_world(flex, "l"), DIMS, 0.5) == (want, False), flex
        assert rotation_observable(_arm_world(flex, "r"), DIMS, 0.5) == (False, want), flex
    hidden = _arm_world(90.0)
    hidden[15, 3] = 0.2                          # the wrist below the visibility the fit drops landmarks at
    assert rotation_observable(hidden, DIMS, 0.5) == (False, False)
    assert rotation_observable(None, DIMS, 0.5) == (False, False)
    # a shorter forearm moves the wrist less: the same bend tells less
    child = BodyDimensions.from_height(1.1)
    assert rotation_observable(_arm_world(70.0), DIMS, 0.5)[0] and not rotation_observable(_arm_world(70.0), child, 0.5)[0]


@pytest.mark.parametrize("mode", ["image", "video"])
def test_hands_clasped_before_the_chest_get_their_elbows_only_with_the_rotation(mode):
    """The paper's arm cannot put a bent forearm across the chest; searching the rotation (with world
    landmarks) finds the elbows and reports the rotation; without world landmarks, or turned off, it does not."""
    cfg = FitConfig(body_height_m=1.7, shoulder_rotation=True)
    for yaw in (20.0, 45.0):
        lm, w, k = _scene(_clasped(yaw), int(yaw))
        with_rot = _fit(cfg, lm, k, w, mode)
        without = _fit(cfg, lm, k, None, mode)
        off = _fit(replace(cfg, shoulder_rotation=False), lm, k, w, mode)
        assert with_rot.ok and without.ok and off.ok
        assert with_rot.extra["mode"] == mode
        err = {name: max(abs(r.joint_angles_deg[f"theta_el_{s}"] - 85.0) for s in "lr")
               for name, r in (("with", with_rot), ("without", without), ("off", off))}
        assert err["with"] < 10.0, (yaw, err)
        assert err["without"] > 2 * err["with"] and err["off"] > 2 * err["with"], (yaw, err)
        rot = with_rot.extra["shoulder_rotation_deg"]
        assert set(rot) == {"psi_sh_l", "psi_sh_r"} and all(abs(v - 55.0) < 15.0 for v in rot.values()), rot
        assert "shoulder_rotation_deg" not in without.extra and "shoulder_rotation_deg" not in off.extra


def test_a_world_judged_garbage_lends_the_fit_no_rotation(monkeypatch):
    """World landmarks whose depths no hypothesis agrees with (fitting.depth_term.usable: the tracker on
    another body) are not used: the frame is solved again with the paper's arm, exactly as without them."""
    import posed.fitting.fitter as fitter_module

    lm, w, k = _scene(_clasped(30.0), 2)
    cfg = FitConfig(body_height_m=1.7, shoulder_rotation=True)
    used = _fit(cfg, lm, k, w, "image")
    assert used.extra["evidence"] == ["landmarks", "world"] and "shoulder_rotation_deg" in used.extra
    monkeypatch.setattr(fitter_module, "usable", lambda fit, depth: False)
    judged = _fit(cfg, lm, k, w, "image")
    plain = _fit(cfg, lm, k, None, "image")
    assert judged.ok and judged.extra["evidence"] == ["landmarks"]
    assert "shoulder_rotation_deg" not in judged.extra
    assert judged.joint_angles_deg == plain.joint_angles_deg and judged.joints_3d == plain.joints_3d


def test_the_analytic_start_puts_a_turned_forearm_on_its_landmarks():
    """An arm solved from its own 2D landmarks (refine.limb_from_observation, the analytic starts and the limbs'
    depth mirrors): with the rotation free the forearm lands exactly on its observed 2D direction, either depth
    sign of the upper arm, the rotation within its limits; the paper's arm only as near as its hinge plane
    allows."""
    from posed.fitting import forward_kinematics as FK
    from posed.fitting import refine

    cfg = FitConfig(body_height_m=1.7, shoulder_rotation=True)
    lm = S.render(_clasped(30.0), dims=DIMS, image_size=SIZE)       # orthographic, no noise
    xy, w, _ = P.landmark_weights(lm, cfg)
    miss = {}
    for rotation in (False, True):
        frame = P.pack(xy, w, DIMS, cfg, P.reference_scale(xy, w, DIMS), rotation=rotation)
        obs = frame.data[L.D_OBS:L.D_OBS + 2 * L.N_LM].reshape(L.N_LM, 2)
        lo, hi = P.limits(rotation)
        miss[rotation] = []
        for seed, limb, sign in itertools.product(P.orientation_seeds(frame, DIMS, *P.image_box(cfg, rotation)),
                                                  (refine.LIMB_ARM_L, refine.LIMB_ARM_R), (1.0, -1.0)):
            out = np.empty(L.N_VAR)
            refine.limb_from_observation(seed, frame.data, limb, sign, out)
            psi = [L.X_PSISH_L, L.X_PSISH_R]
            assert np.all(lo[psi] <= out[psi]) and np.all(out[psi] <= hi[psi])
            pts_b, pts_c = np.empty((L.N_POINTS, 3)), np.empty((L.N_POINTS, 3))
            FK.model_points(out, frame.data, pts_b, pts_c)
            el, wr = L.P_EL_L + limb, L.P_WR_L + limb      # the forearm, metres in the image plane
            seen = (obs[wr] - obs[el]) * DIMS.body_height_m / out[L.X_GAMMA]
            at_limit = out[psi[limb]] in (lo[psi[limb]], hi[psi[limb]])   # the exact rotation out of range
            miss[rotation].append(np.inf if rotation and at_limit else
                                  float(np.linalg.norm(pts_c[wr, :2] - pts_c[el, :2] - seen)))
    exact = [m for m in miss[True] if m < 1e-9]
    assert len(exact) >= 0.75 * len(miss[True]), miss
    assert all(m > 0.02 for m in miss[False]), miss
