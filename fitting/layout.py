"""Index layouts of the numba kernels' flat arrays: where each quantity sits in ``x``, ``fixed``, ``dims``,
the model points, one frame's ``data``, the loss work array and the least-squares residual vector.

Plain integer constants, no code: numba freezes module constants into the machine code of every kernel that
reads them, so this file counts as a source of every kernel for the cache guard (``fitting.jitcache``).
Inside the kernels angles are radians and lengths metres.
"""

from __future__ import annotations

# --- x (21): the paper's eq. (6) order (fitting.result.VARIABLE_NAMES), then the two below ---
# x[X_GAMMA] is the size factor relative to the frame's reference scale (1 = the scale estimated from the
# landmarks); the rest are angles theta (flexion), phi (abduction / lateral), psi (twist).
X_GAMMA, X_TBD, X_PBD, X_SBD, X_TTR, X_PTR, X_STR = 0, 1, 2, 3, 4, 5, 6   # gamma, theta/phi/psi of bd, tr
X_THP_L, X_TKN_L, X_THP_R, X_TKN_R = 7, 8, 9, 10                          # theta_hp_l, theta_kn_l, ...
X_TSH_L, X_TEL_L, X_TSH_R, X_TEL_R = 11, 12, 13, 14                       # theta_sh_l, theta_el_l, ...
X_PHP_L, X_PHP_R, X_PSH_L, X_PSH_R = 15, 16, 17, 18                       # phi_hp_l, phi_hp_r, phi_sh_*
# beyond the paper's 19: the upper arms' rotation about their own axis (fitting.result.SHOULDER_ROTATION_NAMES),
# searched only where BlazePose's world landmarks tell the arms' depth (else its box is [0, 0]: the paper's arm)
X_PSISH_L, X_PSISH_R = 19, 20                                              # psi_sh_l, psi_sh_r
N_VAR = 21

# --- fixed (8): joint angles that are not optimized ---
# theta_hd, psi_hd, psi_hp_l, psi_hp_r, theta_an_l, phi_an_l, theta_an_r, phi_an_r
F_THD, F_PHD, F_PSIHP_L, F_PSIHP_R, F_TAN_L, F_PAN_L, F_TAN_R, F_PAN_R = 0, 1, 2, 3, 4, 5, 6, 7
N_FIXED = 8

# --- dims (11): fitting.body.BodyDimensions in field order, metres ---
DM_H, DM_TRUNK, DM_SH, DM_HP, DM_UA, DM_FA, DM_HAND, DM_TH, DM_SK, DM_ANK, DM_FOOT = range(11)
N_DIMS = 11

# --- model points (19 x 3): the 12 body landmarks in BODY_LANDMARKS order, then the rest ---
# Pelvis frame or camera axes, metres, origin at the mid-hip.
P_SH_L, P_SH_R, P_EL_L, P_EL_R, P_WR_L, P_WR_R = 0, 1, 2, 3, 4, 5
P_HP_L, P_HP_R, P_KN_L, P_KN_R, P_AN_L, P_AN_R = 6, 7, 8, 9, 10, 11
P_HEEL_L, P_HEEL_R, P_TOE_L, P_TOE_R, P_HEAD, P_MIDSH, P_COM = 12, 13, 14, 15, 16, 17, 18
N_POINTS = 19
N_LM = 12   # the landmarks: points 0 .. 11

# --- data: everything one frame's loss needs (built by fitting.problem.pack) ---
D_OBS = 0             # 24: observed landmarks, normalized image units, (x, y) of landmark i at D_OBS + 2 i
D_W = 24              # 12: landmark weights (0 = not used)
D_DIMS = 36           # 11: dims, DM_* order
D_FIXED = 47          # 8: fixed joint angles, F_* order
D_PROJ = D_FIXED + N_FIXED   # 5: the camera, PJ_* order
PJ_MODE, PJ_FN_X, PJ_FN_Y, PJ_OFF_X, PJ_OFF_Y = 0, 1, 2, 3, 4
# PJ_MODE: PROJ_ORTHOGRAPHIC (0) or 1 for perspective. Perspective only: PJ_FN_* the focal lengths in
# normalized units (fx / scale_px, fy / scale_px); PJ_OFF_* the offset from the observations' origin (the
# weighted landmark centroid) to camera-centred normalized coordinates (observed + offset).
PROJ_ORTHOGRAPHIC = 0.0
D_LW = D_PROJ + 5    # 17: loss weights, LW_* order
LW_COM, LW_SYM, LW_SAG_TR, LW_COR_TR, LW_TRAN_TR, LW_SAG_SH, LW_COR_SH = 0, 1, 2, 3, 4, 5, 6
LW_NULL, LW_PRIOR_TR, LW_PRIOR_HP, LW_PRIOR_UP = 7, 8, 9, 10
LW_COM_MODE, LW_CONTACT, LW_MARGIN, LW_SEAT = 11, 12, 13, 14
LW_LIMIT = 15         # weight of the joint-limit hinge (refinement only)
LW_COR_HP = 16        # weight of P_sp(phi_hp, hp adduction max) [beyond the paper]
N_LW = 17
COM_FEET, COM_SUPPORT = 0, 1   # values of data[D_LW + LW_COM_MODE]
D_TH = D_LW + N_LW    # 6: penalty thresholds (rad), TH_* order
TH_TR_FLEX_MIN = 0    # torso flexion minimum (P_sn on theta_tr)
TH_TR_LATERAL = 1     # torso lateral bend +- (P_d on phi_tr)
TH_TR_TWIST = 2       # torso twist +- (P_d on psi_tr)
TH_SH_FLEX_MIN = 3    # shoulder flexion minimum (P_sn on theta_sh_*)
TH_SH_ADD_MAX = 4     # shoulder adduction maximum (P_sp on phi_sh_*)
TH_HP_ADD_MAX = 5     # hip adduction maximum (P_sp on phi_hp_*)
N_TH = 6
D_LIM_LO = D_TH + N_TH            # 21 joint limits (refinement hinge), x order
D_LIM_HI = D_LIM_LO + N_VAR       # 21
D_PRIOR = D_LIM_HI + N_VAR        # 1: weight lambda of the pose prior (refinement only; 0 = off)
D_PRIOR_MU = D_PRIOR + 1          # 21: prior means (kernel units)
D_PRIOR_SIG = D_PRIOR_MU + N_VAR  # 21: prior standard deviations (<= 0: no prior on that variable)
D_PRIOR_PARTNER = D_PRIOR_SIG + N_VAR  # 21: partner variable (prior on x_k - x_partner), -1 for none
D_DEPTH = D_PRIOR_PARTNER + N_VAR  # 12: depth targets: landmark i's depth relative to the mid-hip (m)
D_DEPTH_W = D_DEPTH + N_LM         # 12: weights of the depth rows (0 = no depth; refinement only)
FLEX_VARS = (X_TKN_L, X_TKN_R, X_TEL_L, X_TEL_R)   # the hinges whose flexion a measurement may pull on
N_FLEX = 4
D_FLEX = D_DEPTH_W + N_LM          # 4: measured flexion of the FLEX_VARS hinges (kernel units)
D_FLEX_W = D_FLEX + N_FLEX         # 4: weights of the flexion rows (0 = none; refinement only)
D_LEVEL = D_FLEX_W + N_FLEX      # 10: the level frame: a flag (0 = the camera is level, the rest unused), then
#                                   R_CL row-major (camera axes of the level frame's x, y = down, z; fitting.vertical)
D_SIZE = D_LEVEL + 10

# --- work array of the loss: one (W_ROWS, 3) float64 array, no views in the hot path ---
N_SLOTS = N_VAR + N_FIXED     # trig-table slots: x[k] at slot k (slot 0 unused), fixed[k] at slot N_VAR + k
W_PTS_B = 0                   # 19 rows: model points in the pelvis frame
W_PTS_C = W_PTS_B + N_POINTS  # 19 rows: in camera axes
W_PROJ = W_PTS_C + N_POINTS   # 12 rows: normalized image coordinates (columns 0, 1; 1 / depth in column 2)
W_TRIG = W_PROJ + N_LM        # 29 rows: (angle, cos, sin) per slot, recomputed only when the angle changes
W_RTR = W_TRIG + N_SLOTS      # 3 rows: torso rotation (pelvis from torso), row-major
W_RBD = W_RTR + 3             # 3 rows: body rotation R_CB
W_SIG = W_RBD + 3             # 1 row: signatures of the dims (column 0) and level frame (1) the points were computed with
W_ROWS = W_SIG + 1

# --- least-squares residual vector of the refinement (fitting.jacobian) ---
N_PEN = 9                     # penalty hinges: the paper's 7 and the two hip adductions
R_LM = 0                      # 24: landmark i, axis c (0 = x, 1 = y) at R_LM + 2 i + c
R_PEN = R_LM + 2 * N_LM       # 9: penalty hinges, fitting.penalties.PENALTY_HINGES order
R_LIM = R_PEN + N_PEN         # 21: joint-limit hinges, x order
R_PRIOR = R_LIM + N_VAR       # 21: pose-prior rows, x order (zero where there is no prior)
R_FLEX = R_PRIOR + N_VAR      # 4: flexion rows w_h (x_FLEX_VARS[h] - flex_h), FLEX_VARS order (zero without)
R_DEPTH = R_FLEX + N_FLEX     # 12: depth rows w_i (Z_i - target_i) (zero without depth)
N_RES = R_DEPTH + N_LM
