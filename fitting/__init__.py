"""From 2D landmarks to 3D joint angles: the humanoid model and its uDEAS fit (numpy and numba only).

Other packages import these names from ``fitting`` itself, never from its modules:

* the fit: ``Fitter(config: FitConfig)`` with ``fit(landmarks (33x5) | None, seq, t, image_size, mode,
  intrinsics, depth_m, world, gravity) -> FitResult``, ``reset()`` and ``warmup()`` (compiles the numba
  kernels); ``FitConfig`` is the config section ``fitting``; ``level_frame`` checks a gravity the fit would
  take (fitting.vertical: ValueError for anything but three finite numbers not all 0).
* the result of one frame: ``FitResult`` and the names of its fields: ``VARIABLE_NAMES`` (the 19 fitted
  variables), ``JOINT_ANGLE_NAMES`` (23), ``BODY_ANGLE_NAMES`` (3), ``JOINT_3D_NAMES`` (12).
* what a frame measured, the one rule every view and topic applies (fitting.measured): ``Measured`` (a
  result's ``measured``), ``measured_landmarks`` (the rule on 33 landmarks), ``ANGLE_NEEDS`` (the landmarks
  each angle needs), ``FIXED_ANGLE_NAMES`` (never measured); the plain names of the angles,
  ``ANGLE_PLAIN_NAMES`` (``theta_kn_l`` -> ``left knee flexion``), ``ANGLE_REMARKS`` and ``angle_symbol``.
* the body: ``BodyDimensions`` (link lengths), the calibration file (``read_calibration``,
  ``write_calibration``, ``CalibrationError``) and ``calibrate`` (per-user lengths from a recording of the
  person standing; ``CalibrationFailed``).
* the model in plain NumPy (what the simulators render): ``Pose``, ``joints_3d``, ``landmarks_camera``, and
  the 12 BlazePose landmarks the fit uses, ``BODY_LANDMARKS`` (indices) and ``BODY_LANDMARK_NAMES``.

The names load on first use (PEP 562): ``import fitting`` costs nothing, and only ``Fitter`` pulls in numba.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from posed.fitting.angle_names import PLAIN_NAMES as ANGLE_PLAIN_NAMES
    from posed.fitting.angle_names import REMARKS as ANGLE_REMARKS
    from posed.fitting.angle_names import symbol as angle_symbol
    from posed.fitting.body import BodyDimensions, CalibrationError, read_calibration, write_calibration
    from posed.fitting.calibration import CalibrationFailed, calibrate
    from posed.fitting.config import FitConfig
    from posed.fitting.fitter import Fitter
    from posed.fitting.kinematics import (
        BODY_LANDMARK_NAMES,
        BODY_LANDMARKS,
        Pose,
        joints_3d,
        landmarks_camera,
    )
    from posed.fitting.measured import FIXED as FIXED_ANGLE_NAMES
    from posed.fitting.measured import NEEDS as ANGLE_NEEDS
    from posed.fitting.measured import Measured, measured_landmarks
    from posed.fitting.result import (
        BODY_ANGLE_NAMES,
        JOINT_3D_NAMES,
        JOINT_ANGLE_NAMES,
        VARIABLE_NAMES,
        FitResult,
    )
    from posed.fitting.vertical import level_frame

__all__ = [
    "ANGLE_NEEDS",
    "ANGLE_PLAIN_NAMES",
    "ANGLE_REMARKS",
    "BODY_ANGLE_NAMES",
    "BODY_LANDMARKS",
    "BODY_LANDMARK_NAMES",
    "JOINT_3D_NAMES",
    "JOINT_ANGLE_NAMES",
    "Measured",
    "VARIABLE_NAMES",
    "BodyDimensions",
    "CalibrationError",
    "CalibrationFailed",
    "FIXED_ANGLE_NAMES",
    "FitConfig",
    "FitResult",
    "Fitter",
    "Pose",
    "angle_symbol",
    "calibrate",
    "joints_3d",
    "landmarks_camera",
    "level_frame",
    "measured_landmarks",
    "read_calibration",
    "write_calibration",
]

# public name -> (module that defines it, its name there)
_ORIGIN = {
    "BodyDimensions": ("posed.fitting.body", "BodyDimensions"),
    "CalibrationError": ("posed.fitting.body", "CalibrationError"),
    "read_calibration": ("posed.fitting.body", "read_calibration"),
    "write_calibration": ("posed.fitting.body", "write_calibration"),
    "CalibrationFailed": ("posed.fitting.calibration", "CalibrationFailed"),
    "calibrate": ("posed.fitting.calibration", "calibrate"),
    "FitConfig": ("posed.fitting.config", "FitConfig"),
    "Fitter": ("posed.fitting.fitter", "Fitter"),
    "BODY_LANDMARKS": ("posed.fitting.kinematics", "BODY_LANDMARKS"),
    "BODY_LANDMARK_NAMES": ("posed.fitting.kinematics", "BODY_LANDMARK_NAMES"),
    "Pose": ("posed.fitting.kinematics", "Pose"),
    "joints_3d": ("posed.fitting.kinematics", "joints_3d"),
    "landmarks_camera": ("posed.fitting.kinematics", "landmarks_camera"),
    "ANGLE_PLAIN_NAMES": ("posed.fitting.angle_names", "PLAIN_NAMES"),
    "ANGLE_REMARKS": ("posed.fitting.angle_names", "REMARKS"),
    "angle_symbol": ("posed.fitting.angle_names", "symbol"),
    "ANGLE_NEEDS": ("posed.fitting.measured", "NEEDS"),
    "FIXED_ANGLE_NAMES": ("posed.fitting.measured", "FIXED"),
    "Measured": ("posed.fitting.measured", "Measured"),
    "measured_landmarks": ("posed.fitting.measured", "measured_landmarks"),
    "BODY_ANGLE_NAMES": ("posed.fitting.result", "BODY_ANGLE_NAMES"),
    "JOINT_3D_NAMES": ("posed.fitting.result", "JOINT_3D_NAMES"),
    "JOINT_ANGLE_NAMES": ("posed.fitting.result", "JOINT_ANGLE_NAMES"),
    "VARIABLE_NAMES": ("posed.fitting.result", "VARIABLE_NAMES"),
    "FitResult": ("posed.fitting.result", "FitResult"),
    "level_frame": ("posed.fitting.vertical", "level_frame"),
}


def __getattr__(name: str):
    try:
        module, attr = _ORIGIN[name]
    except KeyError:  # also how ``from fitting import udeas`` finds the submodule
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}") from None
    value = getattr(importlib.import_module(module), attr)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
