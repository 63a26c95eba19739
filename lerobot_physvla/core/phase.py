"""Branch A's phase finite-state machine (paper eq. 3, App. A).

Phases come from geometry alone (eq. 3):
    approach   d_obj_xy >= delta_grasp, object not lifted
    grasp      d_obj_xy <  delta_grasp, object not lifted
    transport  object lifted, d_tgt_xy >= delta_grasp
    place      object lifted, d_tgt_xy <  delta_grasp
where "lifted" means obj_z - obj_rest_z > h_lift (h_lift_m; the paper names no value), and d_*_xy are horizontal distances
from the end-effector, in metres.

Each phase's correction lives in `core/corrections/` (one file each); `core/branch_a.py` runs
the FSM and the phase's correction over B envs.
"""

from __future__ import annotations

import math
from enum import IntEnum

import numpy as np
from numba import njit

APPROACH, GRASP, TRANSPORT, PLACE = 0, 1, 2, 3


class Phase(IntEnum):
    APPROACH = APPROACH
    GRASP = GRASP
    TRANSPORT = TRANSPORT
    PLACE = PLACE


PHASE_NAMES = tuple(p.name.lower() for p in Phase)


@njit(cache=True, error_model="numpy")
def phase_of(d_obj_xy: float, d_tgt_xy: float, lift_m: float, delta_grasp_m: float, h_lift_m: float) -> int:
    """Eq. 3 for one env.

    Eq. 3 leaves "lifted and d_obj_xy >= delta_grasp" to both approach and transport/place. A
    lifted object is in the hand (a rim grasp of a LIBERO bowl holds it ~5 cm off its origin, and
    it swings), and approach's veto would open the gripper and drop it, so lifted wins.
    """
    if lift_m > h_lift_m:
        return PLACE if d_tgt_xy < delta_grasp_m else TRANSPORT
    return APPROACH if d_obj_xy >= delta_grasp_m else GRASP


@njit(cache=True, error_model="numpy")
def detect_phase(d_obj_xy, d_tgt_xy, lift_m, delta_grasp_m, h_lift_m):
    """Phase per env (eq. 3), int8 values of `Phase`, for (B,) distances and lifts in metres."""
    out = np.empty(d_obj_xy.shape[0], np.int8)
    for i in range(out.shape[0]):
        out[i] = phase_of(d_obj_xy[i], d_tgt_xy[i], lift_m[i], delta_grasp_m, h_lift_m)
    return out


@njit(cache=True, error_model="numpy")
def xy_distance(a, b):
    """Horizontal distance between (B, 3) points, metres."""
    out = np.empty(a.shape[0])
    for i in range(a.shape[0]):
        out[i] = math.hypot(a[i, 0] - b[i, 0], a[i, 1] - b[i, 1])
    return out
