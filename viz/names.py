"""Plain names of the fitted angles (what a caregiver reads), next to the model's symbols (fitting.result),
and how the pictures group them. The names themselves are fitting's (``fitting.ANGLE_PLAIN_NAMES``: the client
and every view use the same). Also the words every view uses for what a fit's 3D came from (``evidence_text``).

The model holds some of its 23 joint angles fixed (head, hip rotation, ankles: no landmark the fit uses
observes them); they are not measurements and are never drawn. ``MEASURED_ANGLES`` are the ones the fit
estimates; whether a frame measured one is ``FitResult.measured`` (fitting.measured). Sign convention
(docs/body-model.md): flexion, adduction and internal rotation positive.
"""

from __future__ import annotations

from posed.fitting import ANGLE_PLAIN_NAMES, ANGLE_REMARKS, FIXED_ANGLE_NAMES

# plain name (remark): "trunk flexion (forward bend, relative to the pelvis)" (fitting.angle_names)
ANGLE_LABELS: dict[str, str] = {k: f"{v} ({ANGLE_REMARKS[k]})" if k in ANGLE_REMARKS else v
                                for k, v in ANGLE_PLAIN_NAMES.items()}

# the angles the fit holds fixed (fitting.measured.FIXED): no landmark observes them
FIXED_ANGLES = FIXED_ANGLE_NAMES
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
    """The plain name without the remark: ``left knee flexion``."""
    return ANGLE_PLAIN_NAMES.get(name, name)


def side(name: str) -> str:
    """``left``, ``right`` or ``""`` (the trunk and the body)."""
    return {"l": "left", "r": "right"}.get(name.rsplit("_", 1)[-1], "") if name.count("_") >= 2 else ""


# the fit's evidence and lens (docs/formats.md, fit result ``evidence`` and ``lens``) in the words the views use
EVIDENCE_WORDS = {"landmarks": "2D landmarks", "world": "BlazePose 3D", "depth": "depth camera"}
LENS_WORDS = {"assumed": "assumed lens"}   # "given" (the camera's own intrinsics) goes without saying


def evidence_text(evidence, lens: str | None = None) -> str:
    """``3D from: 2D landmarks + BlazePose 3D, assumed lens``; "" when the fit did not say (an older
    recording's fit). The lens is named only when it was assumed (the source gave no intrinsics: the 3D's
    depth is relative, with no distance in metres)."""
    if not evidence:
        return ""
    text = "3D from: " + " + ".join(EVIDENCE_WORDS.get(e, str(e)) for e in evidence)
    return text + (f", {LENS_WORDS[lens]}" if lens in LENS_WORDS else "")
