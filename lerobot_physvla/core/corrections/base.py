"""What every Branch A correction shares: one signature, one parameter vector, one memory row.

Each correction is a numba function of one env that edits the candidate action in place:

    correction(a_raw, a_phys, idx, geo, p, mem, commit) -> None

    a_raw   (A,) float   the policy's action, action units (read only)
    a_phys  (A,) float   the candidate, action units: read, then written
    idx     (4,) int     action channels [x, y, z, gripper] (gripper = -1 if the layout has none)
    geo     (N_GEO,)     geometry of this env: eef xyz, object xyz, target xyz (m, world),
                         d_obj_xy, d_tgt_xy (m), lift = object height above its rest (m),
                         fingers = the gripper's opening (m)
    p       (N_PARAMS,)  parameters, indexed by the constants below, units in their names
    mem     (N_MEM,)     this env's memory (EMA state); written only when commit is True
    commit  bool         True for the step about to execute (a chunk's first), False for
                         look-ahead steps of a chunk, which must leave memory untouched

The composer (`core/branch_a.py`) copies a_raw into a_phys, calls the phase's correction, and
clips to the action bounds.
"""

from __future__ import annotations

import numpy as np

from lerobot_physvla.core.config import PLACE_RULES, ActionLayout, PhysVLAConfig

# idx
X, Y, Z, GRIPPER = range(4)
# geo
EEF, OBJ, TGT = 0, 3, 6  # xyz triples, m
D_OBJ_XY, D_TGT_XY, LIFT, FINGERS = 9, 10, 11, 12  # m
N_GEO = 13
# p
(BETA, OFFSET_X_M, OFFSET_Y_M, OFFSET_Z_M, LIFT_BIAS_U, ALPHA_TRANSPORT, D_THRESH_M, METRES_PER_UNIT,
 GRIPPER_OPEN, LOW, HIGH, ALPHA_TEMPORAL, PLACE_RULE, REDIRECT_GAIN, PHASE_REF_OBJECT, REDIRECT_TOL_M,
 HOLD_STEPS, RELEASE_CARRY, ASSIST_M, ASSIST_STEPS, ASSIST_STILL_HAND, LIFT_ASSIST_U, LIFT_AT_REST,
 RIM_GUIDE_M, RIM_GUIDE_GRASP) = range(25)
N_PARAMS = 25
# mem
EMA = 0  # 3 entries: x, y, z, action units
ACTIVE = 3  # 1.0 once the EMA holds a value (transport: the previous step was in transport)
HOLD = 4  # place_rule=release_veto: control steps the release has been held back in a row
CARRIED = 5  # release_carry: 1.0 while the object carried to the place phase is still at the hand
STALL = 6  # release_assist_m: control steps in a row the object has been held still over the target
ANCHOR = 7  # 3 entries: assist_still=hand: the end effector where the hold began, m
LIFT_STALL = 10  # lift_assist_u: steps in a row held still unlifted (>= assist_steps: lifting; -1: spent)
LIFT_ANCHOR = 11  # 4 entries: lift_assist_u: the end effector (m, xyz) and the fingers' opening (m) where the hold began
RIM_SETTLE_STEPS = 5  # rim_guide_m: a hand that moved under RIM_SETTLE_M in this many control steps has settled
RIM_TRACK = 15  # 2 x RIM_SETTLE_STEPS entries: rim_guide_m: the end effector's x, y (m) over the last steps
RIM_AT = RIM_TRACK + 2 * RIM_SETTLE_STEPS  # rim_guide_m: steps recorded so far (the next slot: this mod RIM_SETTLE_STEPS)
RIM_ON = RIM_AT + 1  # rim_guide_m: 1.0 while the guide pulls (until the grasp phase, or the rim with
# rim_guide_into_grasp, or a close)
N_MEM = RIM_ON + 1
CARRY_REACH_M = 0.10  # release_carry: the object counts as at the hand within this of it (3-D), m


def channel_index(layout: ActionLayout) -> np.ndarray:
    """idx for a layout: [x, y, z, gripper or -1]."""
    return np.array([*layout.pos, -1 if layout.gripper is None else layout.gripper], dtype=np.intp)


def params(cfg: PhysVLAConfig, layout: ActionLayout) -> np.ndarray:
    """p for a configuration and layout (metres converted to action units where the name says _U)."""
    p = np.empty(N_PARAMS)
    p[BETA] = cfg.beta
    p[OFFSET_X_M : OFFSET_Z_M + 1] = cfg.grasp_offset_m
    p[LIFT_BIAS_U] = cfg.lift_bias_m / layout.metres_per_unit
    p[ALPHA_TRANSPORT] = cfg.alpha_transport
    p[D_THRESH_M] = cfg.d_thresh_m
    p[METRES_PER_UNIT] = layout.metres_per_unit
    p[GRIPPER_OPEN] = layout.gripper_open
    p[LOW], p[HIGH] = layout.low, layout.high
    p[ALPHA_TEMPORAL] = cfg.alpha_temporal
    p[PLACE_RULE] = PLACE_RULES.index(cfg.place_rule)  # 0 decelerate, 1 redirect, 2 release_veto
    p[REDIRECT_GAIN] = cfg.redirect_gain
    p[PHASE_REF_OBJECT] = cfg.phase_ref == "object"
    p[REDIRECT_TOL_M] = cfg.redirect_tol_m
    p[HOLD_STEPS] = cfg.hold_steps
    p[RELEASE_CARRY] = cfg.release_carry
    p[ASSIST_M] = cfg.release_assist_m
    p[ASSIST_STEPS] = cfg.assist_steps
    p[ASSIST_STILL_HAND] = cfg.assist_still == "hand"
    p[LIFT_ASSIST_U] = cfg.lift_assist_u
    p[LIFT_AT_REST] = cfg.lift_assist_at_rest
    p[RIM_GUIDE_M] = cfg.rim_guide_m
    p[RIM_GUIDE_GRASP] = cfg.rim_guide_into_grasp
    return p
