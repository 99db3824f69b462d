"""Configuration of the 3D fit (config section ``fitting``). docs/body-model.md explains every term."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True)
class FitConfig:
    """uDEAS fit of the humanoid model to the 12 body landmarks (paper sections 2.4 and 4)."""

    body_height_m: float = field(
        default=1.60, metadata={"doc": "body height used for link lengths when no calibration is given",
                                "unit": "m", "range": (0.8, 2.3)}
    )
    calibration: str = field(default="", metadata={"doc": "user.yaml from `posed calibrate`; empty = none"})
    restarts: int = field(default=6, metadata={"doc": "uDEAS restarts (image mode)", "range": (1, 200)})
    row_init: int = field(default=3, metadata={"doc": "uDEAS initial row length m0", "range": (1, 30)})
    row_max: int = field(default=6, metadata={"doc": "uDEAS maximal row length mf", "range": (1, 30)})
    seed: int = field(default=0, metadata={"doc": "random seed (same seed, same result)", "range": (0, None)})
    bounds: str = field(
        default="wide", metadata={"doc": "image-mode search box: wide (also lying and fallen people) or paper "
                                         "(Table 1: body tilt within 10 deg)", "choices": ("wide", "paper")}
    )
    seed_orientation: bool = field(
        default=True, metadata={"doc": "start the first restarts from the body orientations computed from "
                                       "the hips and shoulders (both depth mirrors)"}
    )
    analytic_seeds: bool = field(
        default=True, metadata={"doc": "image mode: also refine starts whose limbs are solved from their 2D "
                                       "landmarks on each seeded body orientation"}
    )
    refine: bool = field(
        default=True, metadata={"doc": "Levenberg-Marquardt refinement (analytic Jacobian) after uDEAS"}
    )
    refine_iterations: int = field(
        default=30, metadata={"doc": "most Levenberg-Marquardt iterations per candidate", "range": (1, 500)}
    )
    pose_prior: float = field(
        default=3.0, metadata={"doc": "weight of the pose prior (left/right limb symmetry, straight spine) in "
                                      "the refinement, scaled by the landmark noise estimated from the residual "
                                      "(0 = off; an exact fit gets none); see docs/body-model.md",
                               "range": (0.0, None)}
    )
    pose_prior_max_noise: float = field(
        default=0.015, metadata={"doc": "cap of the landmark noise estimated from the residual, fraction of body "
                                       "height (a larger residual is a model mismatch, not noise)",
                                "range": (0.0, 1.0)}
    )
    refine_candidates: int = field(
        default=3, metadata={"doc": "image mode: refine this many of the best distinct restart results",
                             "range": (1, 50)}
    )
    limb_mirrors: bool = field(
        default=True, metadata={"doc": "image mode: also refine each limb's depth mirror and keep it if the loss "
                                       "is lower (orthographic ambiguity)"}
    )
    video_hypotheses: bool = field(
        default=True, metadata={"doc": "video mode: also refine each limb's depth mirror of the previous solution "
                                       "and this frame's own analytic starts, and choose by temporal "
                                       "consistency (off: faster, follows the previous solution only)"}
    )
    video_restarts: int = field(
        default=0, metadata={"doc": "video mode: uDEAS restarts within +-video_window_deg of the previous "
                                    "solution, one more hypothesis (the paper's search; 0 = off)",
                             "range": (0, 200)}
    )
    video_row_init: int = field(default=2, metadata={"doc": "video mode: uDEAS initial row length",
                                                     "range": (1, 30)})
    video_row_max: int = field(default=5, metadata={"doc": "video mode: uDEAS maximal row length",
                                                    "range": (1, 30)})
    video_window_deg: float = field(
        default=10.0, metadata={"doc": "video mode: search +- this around the previous frame's angles (paper: 10)",
                                "unit": "deg", "range": (0.5, 180.0)}
    )
    video_window_gamma: float = field(
        default=0.05, metadata={"doc": "video mode: relative search window of the size factor",
                                "range": (0.0, 1.0)}
    )
    video_smoothing: float = field(
        default=1.0, metadata={"doc": "video mode: weight of the previous frame as a prior, scaled by the "
                                      "landmark noise estimated from the residual (0 = off; exact fits get none)",
                               "range": (0.0, None)}
    )
    video_smoothing_deg: float = field(
        default=8.0, metadata={"doc": "deprecated and ignored (it was per frame, so the prior depended on the "
                                      "frame rate); use video_joint_speed_deg_s", "unit": "deg",
                               "range": (0.1, 90.0)}
    )
    video_joint_speed_deg_s: float = field(
        default=500.0, metadata={"doc": "video mode: how fast a joint angle may change, one standard deviation "
                                        "of the prior from the previous frame (scaled by the time between "
                                        "frames)", "unit": "deg/s", "range": (1.0, 5000.0)}
    )
    video_max_gap_s: float = field(
        default=0.5, metadata={"doc": "video mode: a longer gap since the last good fit starts over in image mode",
                               "unit": "s", "range": (0.0, 60.0)}
    )
    video_recover_error: float = field(
        default=0.03, metadata={"doc": "video mode: if the 2D error exceeds this fraction of body height the "
                                       "frame is fitted again in image mode", "range": (0.0, 1.0)}
    )
    world_landmarks: bool = field(
        default=True, metadata={"doc": "use BlazePose's world landmarks (a recording's or the landmark stage's "
                                       "'world') as robust evidence of each limb's depth, when there is no "
                                       "depth camera (fitting.world_term; docs/body-model.md)"}
    )
    shoulder_rotation: bool = field(
        default=False, metadata={"doc": "search each upper arm's rotation about its own axis (hands before "
                                        "the chest, arms folded) where the world landmarks tell it (the elbow "
                                        "bent 54-126 degrees); off, or without them: the paper's shoulder, "
                                        "flexion and adduction only. Off by default: its gain on real video "
                                        "(0.9 mm PA-MPJPE at 10 fps; the squat's elbows) is not confirmed "
                                        "by the untouched mocap source, whose subject's short forearms "
                                        "leave the search idle on most frames (docs/body-model.md, "
                                        "'Shoulder rotation')"}
    )
    learn_proportions: bool = field(
        default=True, metadata={"doc": "video mode without a calibration file: learn the person's proportions "
                                       "(upper arm, forearm, thigh, shank, trunk, hip width; the configured "
                                       "height kept) from the frames (fitting.proportions; docs/body-model.md)"}
    )
    proportions_forget_s: float = field(
        default=30.0, metadata={"doc": "after this long without a fitted video frame the learned proportions "
                                       "are only where new samples start (someone else may come)", "unit": "s",
                                "range": (0.0, 86400.0)}
    )
    projection: str = field(
        default="auto", metadata={"doc": "camera model: orthographic (the paper), perspective (needs "
                                         "intrinsics), or auto (perspective when intrinsics are known; the "
                                         "daemon gives a source without any the lens of "
                                         "falls.camera_hfov_deg, assumed: no root_cam_m)",
                                  "choices": ("auto", "orthographic", "perspective")}
    )
    vertical: str = field(
        default="auto", metadata={"doc": "which way is down for the pelvis-tilt prior and the centre of mass "
                                         "over the feet: auto (gravity when the fit is given it: the daemon "
                                         "gives a RealSense IMU's, else the floor plane measured in the depth "
                                         "image, else the camera's tilt and roll when falls.camera_geometry "
                                         "trusts them as measured, else what the fall detector learned of the "
                                         "camera from people and kept; else the camera's +y) or camera (always the camera's +y: the paper's level camera); "
                                         "see docs/body-model.md",
                                  "choices": ("auto", "camera")}
    )
    visibility_drop: float = field(
        default=0.3, metadata={"doc": "landmarks with visibility below this are not used", "range": (0.0, 1.0)}
    )
    visibility_full: float = field(
        default=0.7, metadata={"doc": "landmarks with visibility above this get full weight (linear between)",
                               "range": (0.0, 1.0)}
    )
    min_landmarks: int = field(
        default=6, metadata={"doc": "fewest usable body landmarks (of 12) for a fit (6: e.g. shoulders, hips and "
                                    "knees, what real extractors give of a person falling; see docs/falls.md)",
                             "range": (4, 12)}
    )
    max_error: float = field(
        default=0.05, metadata={"doc": "reject a fit whose mean 2D error exceeds this fraction of body height",
                                "range": (0.0, 1.0)}
    )
    max_gamma: float = field(
        default=2.0, metadata={"doc": "reject a fit whose standing body would be taller than this many image "
                                      "heights (its landmarks could not all be in view)", "range": (0.1, 100.0)}
    )
    w_com: float = field(
        default=0.01, metadata={"doc": "weight of the centre-of-mass deviation term (paper: 0.01)",
                                "range": (0.0, None)}
    )
    com_mode: str = field(
        default="support", metadata={"doc": "CoM deviation: feet (paper: distance to the centre of the supporting "
                                            "feet) or support (zero inside the support of every body part on "
                                            "the floor, seat included)", "choices": ("feet", "support")}
    )
    com_contact: float = field(
        default=0.06, metadata={"doc": "body parts within this fraction of body height of the lowest one "
                                       "touch the floor", "range": (0.0, 1.0)}
    )
    com_margin: float = field(
        default=1.0, metadata={"doc": "support mode: no CoM penalty within this many support radii",
                               "range": (0.0, 10.0)}
    )
    w_sym: float = field(
        default=0.0, metadata={"doc": "weight of the left/right hip and knee flexion symmetry term "
                                      "(paper: 0.01; it pulls asymmetric poses away from the truth)",
                               "range": (0.0, None)}
    )
    w_sag_tr: float = field(default=0.01, metadata={"doc": "weight of P_sn(theta_tr, tr_flexion_min_deg)",
                                                    "range": (0.0, None)})
    w_cor_tr: float = field(default=0.01, metadata={"doc": "weight of P_d(phi_tr, +-tr_lateral_deg)",
                                                    "range": (0.0, None)})
    w_tran_tr: float = field(default=0.01, metadata={"doc": "weight of P_d(psi_tr, +-tr_twist_deg)",
                                                     "range": (0.0, None)})
    w_sag_sh: float = field(default=0.01, metadata={"doc": "weight of P_sn(theta_sh, sh_flexion_min_deg), each side",
                                                    "range": (0.0, None)})
    w_cor_sh: float = field(default=0.01, metadata={"doc": "weight of P_sp(phi_sh, sh_adduction_max_deg), each side",
                                                    "range": (0.0, None)})
    w_cor_hp: float = field(default=0.01, metadata={"doc": "weight of P_sp(phi_hp, hp_adduction_max_deg), each side "
                                                           "(not in the paper; 0 = off)", "range": (0.0, None)})
    tr_flexion_min_deg: float = field(default=-20.0, metadata={"doc": "lumbar extension beyond this is penalized (paper: -10)",
                                                               "unit": "deg", "range": (-90.0, 90.0)})
    tr_lateral_deg: float = field(default=20.0, metadata={"doc": "lumbar lateral bend beyond +- this is penalized (paper: 10)",
                                                          "unit": "deg", "range": (0.0, 90.0)})
    tr_twist_deg: float = field(default=25.0, metadata={"doc": "lumbar twist beyond +- this is penalized (paper: 15)",
                                                        "unit": "deg", "range": (0.0, 90.0)})
    sh_flexion_min_deg: float = field(default=-40.0, metadata={"doc": "shoulder extension beyond this is penalized (paper: -10)",
                                                               "unit": "deg", "range": (-180.0, 180.0)})
    sh_adduction_max_deg: float = field(default=10.0, metadata={"doc": "shoulder adduction beyond this is penalized (paper: 0)",
                                                               "unit": "deg", "range": (-90.0, 90.0)})
    hp_adduction_max_deg: float = field(default=0.0, metadata={"doc": "hip adduction beyond this is penalized",
                                                                "unit": "deg", "range": (-90.0, 90.0)})
    w_null: float = field(
        default=0.002, metadata={"doc": "weight of the pelvis-tilt prior inside the uDEAS loss (the tilt is "
                                        "set exactly after refinement)", "range": (0.0, None)}
    )
    prior_lumbar: float = field(
        default=1.0, metadata={"doc": "pelvis-tilt prior: cost per radian of lumbar flexion", "range": (0.0, None)}
    )
    prior_hip: float = field(
        default=0.4, metadata={"doc": "pelvis-tilt prior: cost per radian of hip flexion, each side",
                               "range": (0.0, None)}
    )
    prior_pelvis_upright: float = field(
        default=1.5, metadata={"doc": "pelvis-tilt prior: cost per radian of pelvis tilt from vertical, times "
                                      "the cosine of the torso inclination", "range": (0.0, None)}
    )
    w_limit: float = field(
        default=0.0, metadata={"doc": "refinement: weight of the joint-limit hinge (0: limits are hard clamps)",
                               "range": (0.0, None)}
    )
