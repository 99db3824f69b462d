"""Plain names of the angles a fit reports (what a person reads, and what ``FitResult.angle`` accepts), next to
the model's symbols (fitting.result). Sign convention (docs/body-model.md): flexion, adduction and internal
rotation positive; the trunk's side bend and twist to the person's left positive.

``PLAIN_NAMES``: symbol -> plain name (``theta_kn_l`` -> ``left knee flexion``); ``REMARKS``: what a plain name
alone does not say (shown beside it where there is room). The angles the model holds fixed keep a name too,
but are never measured (fitting.measured).
"""

from __future__ import annotations

PLAIN_NAMES: dict[str, str] = {
    "theta_tr": "trunk flexion",
    "phi_tr": "trunk side bend",
    "psi_tr": "trunk twist",
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
    "theta_bd": "body pitch",
    "phi_bd": "body roll",
    "psi_bd": "body turn",
    "theta_hd": "head flexion",
    "psi_hd": "head turn",
    "psi_hp_l": "left hip rotation",
    "psi_hp_r": "right hip rotation",
    "theta_an_l": "left ankle dorsiflexion",
    "phi_an_l": "left ankle inversion",
    "theta_an_r": "right ankle dorsiflexion",
    "phi_an_r": "right ankle inversion",
}

REMARKS: dict[str, str] = {
    "theta_tr": "forward bend",
    "phi_tr": "to the left +",
    "psi_tr": "to the left +",
    "theta_bd": "the pelvis's forward tilt to the camera",
    "phi_bd": "the pelvis's tilt to its left +, to the camera",
    "psi_bd": "the pelvis's turn to its left +, to the camera",
    **dict.fromkeys(("theta_hd", "psi_hd", "psi_hp_l", "psi_hp_r", "theta_an_l", "phi_an_l", "theta_an_r",
                     "phi_an_r"), "not measured"),
}

_BY_PLAIN = {v: k for k, v in PLAIN_NAMES.items()}


def symbol(name: str) -> str:
    """The model's symbol of an angle named either way (``left knee flexion`` or ``theta_kn_l``); raises
    KeyError listing the plain names for an unknown one."""
    if name in PLAIN_NAMES:
        return name
    key = " ".join(name.lower().replace("_", " ").split())
    if key in _BY_PLAIN:
        return _BY_PLAIN[key]
    raise KeyError(f"no angle named {name!r}; the angles: {', '.join(PLAIN_NAMES.values())} (or their symbols "
                   f"{', '.join(PLAIN_NAMES)})")
