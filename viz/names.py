"""Plain names of the fitted angles (what a caregiver reads), next to the model's symbols (fitting.result).

The model holds some of its 23 joint angles fixed (head, hip rotation, ankles: no landmark the fit uses
observes them); they are not measurements and are never drawn. ``MEASURED_ANGLES`` are the ones the fit
estimates. Sign convention (docs/body-model.md): flexion, adduction and internal rotation positive.
"""

from __future__ import annotations

ANGLE_LABELS: dict[str, str] = {
    "theta_tr": "trunk flexion (forward bend)",
    "phi_tr": "trunk side bend (to the left +)",
    "psi_tr": "trunk twist (to the left +)",
    "theta_sh_l": "left shoulder flexion",
    "theta_sh_r": "right shoulder flexion",
    "phi_sh_l": "left shoulder adduction",
    "phi_sh_r": "right shoulder adduction",
    "theta_el_l": "left elbow flexion",
    "theta_el_r": "right elbow flexion",
    "theta_hp_l": "left hip flexion",
    "theta_hp_r": "right hip flexion",
    "phi_hp_l": "left hip adduction",
    "phi_hp_r": "right hip adduction",
    "theta_kn_l": "left knee flexion",
    "theta_kn_r": "right knee flexion",
    "theta_bd": "body pitch (forward tilt)",
    "phi_bd": "body roll (tilt to its left +)",
    "psi_bd": "body turn (to its left +)",
    # held fixed by the model (not measured): named for completeness, never drawn
    "theta_hd": "head flexion (not measured)",
    "psi_hd": "head turn (not measured)",
    "psi_hp_l": "left hip rotation (not measured)",
    "psi_hp_r": "right hip rotation (not measured)",
    "theta_an_l": "left ankle dorsiflexion (not measured)",
    "phi_an_l": "left ankle inversion (not measured)",
    "theta_an_r": "right ankle dorsiflexion (not measured)",
    "phi_an_r": "right ankle inversion (not measured)",
}

# the angles the fit holds fixed (fitting/reported.py FIXED_NAMES): no landmark observes them
FIXED_ANGLES = ("theta_hd", "psi_hd", "psi_hp_l", "psi_hp_r", "theta_an_l", "phi_an_l", "theta_an_r", "phi_an_r")
MEASURED_ANGLES = tuple(n for n in ANGLE_LABELS if n not in FIXED_ANGLES)

# the angles shown on the overlay video, in reading order
MAIN_ANGLES = ("theta_tr", "theta_hp_l", "theta_hp_r", "theta_kn_l", "theta_kn_r", "theta_el_l", "theta_el_r")

PANELS: dict[str, tuple[str, ...]] = {
    "legs": ("theta_hp_l", "theta_hp_r", "theta_kn_l", "theta_kn_r"),
    "trunk": ("theta_tr", "phi_tr", "psi_tr"),
    "arms": ("theta_sh_l", "theta_sh_r", "theta_el_l", "theta_el_r"),
    "body": ("theta_bd", "phi_bd", "psi_bd"),
}
PANEL_TITLES = {"legs": "hips and knees", "trunk": "trunk", "arms": "shoulders and elbows",
                "body": "whole-body orientation to the camera"}


def label(name: str) -> str:
    """The plain name of angle ``name`` (the symbol itself when unknown)."""
    return ANGLE_LABELS.get(name, name)


def short_label(name: str) -> str:
    """The plain name without the parenthesised remark: ``left knee flexion``."""
    return label(name).split(" (")[0]


def side(name: str) -> str:
    """``left``, ``right`` or ``""`` (the trunk and the body)."""
    return {"l": "left", "r": "right"}.get(name.rsplit("_", 1)[-1], "") if name.count("_") >= 2 else ""
