"""An angle the refinement held at a joint limit is the clamp's value, not a measurement: the result lists it
(``at_limit``) and leaves it out of ``measured`` (so every view says "not measured" instead of showing the
limit as a reading). A straight knee or elbow (0) is a pose, not a clamp."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np

from posed.fitting import FitResult
from posed.fitting import problem as P
from posed.fitting.assemble import at_limit
from posed.fitting.result import VARIABLE_NAMES

ROOT = __import__("pathlib").Path(__file__).resolve().parents[2]


def _x(**deg) -> np.ndarray:
    x = np.zeros(P.LIMIT_LO_RAD.shape[0])
    x[0] = 1.0
    for name, v in deg.items():
        x[VARIABLE_NAMES.index(name)] = np.radians(v)
    return x


def test_at_limit_names_the_clamped_joints_and_not_a_straight_knee():
    assert at_limit(_x()) == []                                       # knees and elbows straight: no clamp
    x = _x(theta_kn_l=165.0, theta_hp_r=140.0, phi_hp_l=-60.0, theta_el_r=30.0, theta_tr=-40.0)
    assert at_limit(x) == ["theta_tr", "theta_kn_l", "theta_hp_r", "phi_hp_l"]
    assert at_limit(_x(theta_kn_l=164.9, theta_hp_r=139.9)) == []
    # the body's own angles (1-3) and the size are never joint limits
    x = _x()
    x[1], x[3] = P.LIMIT_HI_RAD[1], P.LIMIT_LO_RAD[3]
    assert at_limit(x) == []


def test_a_real_fall_fitted_at_the_hip_limit_reports_it_unmeasured(tmp_path, shared_data):
    """urfd_04 (UR Fall): on the floor the fit holds a hip at 140 degrees, its limit, for 0.3 s."""
    out = tmp_path / "fit.jsonl"
    rec = shared_data / "falls/urfd_dev/urfd_04_fall.landmarks.jsonl"
    subprocess.run([sys.executable, "-m", "posed.cli", "fit", str(rec), "-o", str(out)], cwd=ROOT, check=True,
                   capture_output=True, timeout=600)
    lo = dict(zip(VARIABLE_NAMES, P.LIMIT_LO, strict=False))
    hi = dict(zip(VARIABLE_NAMES, P.LIMIT_HI, strict=False))
    listed = 0
    for line in out.read_text().splitlines():
        obj = json.loads(line)
        if not obj.get("ok"):
            continue
        r = FitResult.from_json(obj)
        clamped = obj.get("at_limit", [])
        for name in VARIABLE_NAMES[4:19]:
            v = obj["variables"][name]
            at = abs(v - hi[name]) < 0.01 or (abs(v - lo[name]) < 0.01 and not name.startswith(("theta_kn",
                                                                                               "theta_el")))
            assert at == (name in clamped), (obj["seq"], name, v, clamped)
        for name in clamped:
            listed += 1
            assert r.angle(name) is None and name not in obj["measured"]["angles"], (obj["seq"], name)
            assert obj["joint_angles_deg"][name] == obj["variables"][name]     # the value itself is kept
    assert listed >= 5, "urfd_04's fit reaches the hip limit on the floor"
