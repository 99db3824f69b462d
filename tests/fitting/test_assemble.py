"""fitting.assemble and fitting.reported: the reported values of a solution, rounded, named and ordered as the plain-NumPy
assembly gives them, to the last bit."""

import json

import numpy as np
import pytest

from posed.fitting import forward_kinematics as FK
from posed.fitting import layout as L
from posed.fitting import problem as P
from posed.fitting.assemble import assemble, unobserved
from posed.fitting.depth_term import DepthFit
from posed.fitting.kinematics import BODY_LANDMARK_NAMES
from posed.fitting.reported import FIXED_NAMES, rounded
from posed.fitting.result import JOINT_ANGLE_NAMES, VARIABLE_NAMES, FitResult
from tests.fitting.root_reference import reference_root
from tests.fitting.walking import CAMERA, CONFIG, DIMS, walking_weights


def _reference_assemble(seq, t, x, frame, fixed_deg, *, loss, mp, fit_ms, mode, evals, udeas_s, missing, gamma,
                        depth, rotation=False, lens_assumed=False):
    """The assembly in plain NumPy and Python (np.round of every value, the dicts built by name)."""
    pts_b, pts_c = np.empty((L.N_POINTS, 3)), np.empty((L.N_POINTS, 3))
    FK.model_points(x, frame.data, pts_b, pts_c)
    deg = np.round(P.to_degrees(x), 4).tolist()
    fixed = np.round(fixed_deg, 4).tolist()
    xyz = np.round(pts_c[:L.N_LM], 5).tolist()
    variables = dict(zip(VARIABLE_NAMES, deg[:len(VARIABLE_NAMES)], strict=True))
    variables["gamma"] = round(gamma, 5)
    angles = dict.fromkeys(JOINT_ANGLE_NAMES, 0.0)
    angles.update((n, v) for n, v in zip(FIXED_NAMES, fixed, strict=True) if n in angles)
    angles.update(zip(VARIABLE_NAMES[4:], deg[4:len(VARIABLE_NAMES)], strict=True))
    j3 = {"mid_hip": (0.0, 0.0, 0.0)}
    j3.update(zip(BODY_LANDMARK_NAMES, map(tuple, xyz), strict=True))
    extra = {"mode": mode, "projection": "perspective" if frame.perspective else "orthographic",
             "err2d": float(f"{mp:.6g}"), "err2d_px": float(f"{mp * frame.scale_px:.4g}"), "evals": evals,
             "udeas_ms": float(f"{udeas_s * 1e3:.4g}")}
    if frame.perspective:
        extra["lens"] = "assumed" if lens_assumed else "given"
    root = reference_root(x, frame.data, pts_c, None if depth is None else depth.root_z)
    if rotation:
        extra["shoulder_rotation_deg"] = {"psi_sh_l": deg[L.X_PSISH_L], "psi_sh_r": deg[L.X_PSISH_R]}
    if depth is not None:
        extra["depth_inliers"] = depth.inliers
    if root is not None and not lens_assumed:
        extra["root_cam_m"] = [round(v, 4) for v in root]
    if missing:
        extra["missing"] = missing
        extra["unobserved"] = unobserved(missing)
    return FitResult(seq=seq, t=t, ok=True, loss=float(f"{loss:.6g}"), fit_ms=float(f"{fit_ms:.4g}"),
                     variables=variables, joint_angles_deg=angles, joints_3d=j3, extra=extra)


def _bits(obj):
    """A result's JSON with every float's bits (and its type, key order and signed zeros)."""
    def walk(v):
        if isinstance(v, float):
            return ("f", np.float64(v).tobytes().hex())
        if isinstance(v, dict):
            return [(k, walk(u)) for k, u in v.items()]
        if isinstance(v, (list, tuple)):
            return (type(v).__name__, [walk(u) for u in v])
        return (type(v).__name__, v)
    return walk(obj)


def test_rounded_is_np_round_to_the_last_bit():
    rng = np.random.default_rng(2)
    for i in range(2000):
        scale = 10.0 ** rng.integers(-6, 4)
        v = rng.normal(size=40) * scale
        if i % 3 == 0:   # halfway cases
            v[:20] = (np.round(v[:20] * 2e4) + 0.5) / 1e4
            v[20:] = (np.floor(v[20:] * 1e5) + 0.5) / 1e5
        for decimals in (4, 5):
            got = np.array([rounded(u, 1.0, 10.0 ** decimals) for u in v])
            assert got.tobytes() == np.round(v, decimals).tobytes()
        got = np.array([rounded(u, P.DEG, 1e4) for u in v])
        assert got.tobytes() == np.round(v / P.DEG, 4).tobytes()


@pytest.mark.parametrize("intrinsics", [True, False, "assumed"])
def test_assemble_matches_the_plain_numpy_assembly(intrinsics):
    """Random solutions (signed zeros, halfway angles), with and without a measured depth and missing
    landmarks: every field of the result identical in value, type, bits and order."""
    dims, cfg = DIMS, CONFIG
    xy, w = walking_weights()
    k = CAMERA if intrinsics else None
    rng = np.random.default_rng(5)
    for i in range(60):
        fixed_deg = np.round(rng.normal(size=L.N_FIXED) * 20, 5) if i % 2 else np.zeros(L.N_FIXED)
        frame = P.pack(xy, w, dims, cfg, P.reference_scale(xy, w, dims), k, fixed_deg)
        x = P.to_radians(rng.uniform(P.LIMIT_LO, P.LIMIT_HI))
        if i % 4 == 0:
            x[5:9] = -0.0
            x[9] = P.to_radians(np.full(L.N_VAR, 12.34565))[9]
        depth = (DepthFit(0.5, float(rng.uniform(1.0, 6.0)), int(rng.integers(0, 12)), 0.05, np.zeros(12),
                          np.zeros(12)) if i % 3 == 0 else None)
        missing = [] if i % 5 else ["left_wrist", "right_knee"]
        kw = dict(loss=float(rng.random()), mp=float(rng.random() * 0.1), fit_ms=float(rng.random() * 3),
                  mode="video", evals=int(i), udeas_s=float(rng.random() * 1e-3) if i % 2 else 0.0,
                  missing=missing, gamma=float(rng.uniform(0.5, 2.0)), depth=depth, rotation=i % 3 == 1,
                  lens_assumed=intrinsics == "assumed")
        got = assemble(i, 0.1 * i, x, frame, fixed_deg, **kw)
        want = _reference_assemble(i, 0.1 * i, x, frame, fixed_deg, **kw)
        assert _bits(got.to_json()) == _bits(want.to_json())
        assert json.dumps(got.to_json()) == json.dumps(want.to_json())
        assert _bits(got.joints_3d) == _bits(want.joints_3d)    # tuples, as the dataclass holds them
        assert ("root_cam_m" in got.extra) == (intrinsics is True)   # never metres through an assumed lens
        assert got.extra.get("lens") == {True: "given", False: None, "assumed": "assumed"}[intrinsics]
