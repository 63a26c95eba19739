"""Branch A: the phase finite-state machine and its four phase corrections (paper eq. 3, 5, App. A).

Phases come from geometry alone (eq. 3):
    approach   d_obj_xy >= delta_grasp, object not lifted
    grasp      d_obj_xy <  delta_grasp, object not lifted
    transport  object lifted, d_tgt_xy >= delta_grasp
    place      object lifted, d_tgt_xy <  delta_grasp
where "lifted" means obj_z - obj_rest_z > h_lift (SPEC), and d_*_xy are horizontal distances
from the end-effector, in metres.

Corrections (App. A), on the candidate a_phys, in action units (metres / metres_per_unit):
    approach   premature-grasp veto: gripper <- open
    grasp      a_pos = beta (p* - p_eef) / scale + (1 - beta) a_raw_pos,   p* = p_obj + offset
    transport  a_pos <- alpha a_pos_prev + (1 - alpha) (a_raw_pos + dz+ / scale e_z)
    place      a_pos = min(1, d_tgt_xy / d_thresh) a_raw_pos                 (eq. 5)

The per-env arithmetic is compiled with numba (microseconds an env-step, where small-array numpy
costs ~40); `corrector.Corrector` runs it over B envs with per-env memory.
"""

from __future__ import annotations

import math
from enum import IntEnum

import numpy as np
from numba import njit

from lerobot_physvla.core.state import INVALID_STATE, NONFINITE_ACTION, NONFINITE_STATE, OK

# numba caches a compiled function by its own file only: every cached kernel here calls njit
# functions of this module alone, so editing this file invalidates all of them together.

APPROACH, GRASP, TRANSPORT, PLACE = 0, 1, 2, 3


class Phase(IntEnum):
    APPROACH = APPROACH
    GRASP = GRASP
    TRANSPORT = TRANSPORT
    PLACE = PLACE


PHASE_NAMES = tuple(p.name.lower() for p in Phase)


@njit(cache=True)
def phase_of(d_obj_xy: float, d_tgt_xy: float, lift_m: float, delta_grasp_m: float, h_lift_m: float) -> int:
    """Eq. 3 for one env.

    Eq. 3 leaves "lifted and d_obj_xy >= delta_grasp" to both approach and transport/place. A
    lifted object is in the hand (a rim grasp of a LIBERO bowl holds it ~5 cm off its origin, and
    it swings), and approach's veto would open the gripper and drop it, so lifted wins.
    """
    if lift_m > h_lift_m:
        return PLACE if d_tgt_xy < delta_grasp_m else TRANSPORT
    return APPROACH if d_obj_xy >= delta_grasp_m else GRASP


@njit(cache=True)
def detect_phase(d_obj_xy, d_tgt_xy, lift_m, delta_grasp_m, h_lift_m):
    """Phase per env (eq. 3), int8 values of `Phase`, for (B,) distances and lifts in metres."""
    out = np.empty(d_obj_xy.shape[0], np.int8)
    for i in range(out.shape[0]):
        out[i] = phase_of(d_obj_xy[i], d_tgt_xy[i], lift_m[i], delta_grasp_m, h_lift_m)
    return out


@njit(cache=True)
def xy_distance(a, b):
    """Horizontal distance between (B, 3) points, metres."""
    out = np.empty(a.shape[0])
    for i in range(a.shape[0]):
        out[i] = math.hypot(a[i, 0] - b[i, 0], a[i, 1] - b[i, 1])
    return out


@njit(cache=True)
def branch_a_row(a_raw, a_phys, phase, eef, obj, d_tgt, pos, grip, p, ema, in_transport, commit):
    """Branch A for one env: writes a_phys (A,) from a_raw; updates the transport EMA if commit.

    p holds [beta, grasp offset x, y, z (m), lift bias (units), alpha_transport, d_thresh (m),
    metres_per_unit, gripper_open, low, high]; ema (3,) and in_transport (1,) are this env's memory.
    """
    beta, lift_u, alpha, d_thresh, scale = p[0], p[4], p[5], p[6], p[7]
    for k in range(a_raw.shape[0]):
        a_phys[k] = a_raw[k]
    if phase == APPROACH:
        if grip >= 0:
            a_phys[grip] = p[8]  # premature-grasp veto: gripper open
    elif phase == GRASP:
        for k in range(3):  # metres -> action units with the layout's scale
            a_phys[pos[k]] = beta * (obj[k] + p[1 + k] - eef[k]) / scale + (1.0 - beta) * a_raw[pos[k]]
    elif phase == TRANSPORT:
        first = not in_transport[0]
        for k in range(3):
            x = a_raw[pos[k]] + (lift_u if k == 2 else 0.0)
            prev = x if first else ema[k]
            e = alpha * prev + (1.0 - alpha) * x
            a_phys[pos[k]] = e
            if commit:
                ema[k] = e
    elif phase == PLACE:
        ramp = min(1.0, d_tgt / d_thresh)  # eq. 5
        for k in range(3):
            a_phys[pos[k]] = ramp * a_raw[pos[k]]
    if commit:
        in_transport[0] = phase == TRANSPORT
    for k in range(a_phys.shape[0]):
        a_phys[k] = min(max(a_phys[k], p[9]), p[10])


@njit(cache=True)
def ema_row(a_raw, out, pos, alpha, ema, initialised, commit):
    """Uniform EMA on the position channels (the `temporal` baseline) for one env."""
    for k in range(a_raw.shape[0]):
        out[k] = a_raw[k]
    for k in range(3):
        x = a_raw[pos[k]]
        prev = ema[k] if initialised[0] else x
        e = alpha * prev + (1.0 - alpha) * x
        out[pos[k]] = e
        if commit:
            ema[k] = e
    if commit:
        initialised[0] = True


@njit(cache=True)
def phase_step(a_raw, flat, o, pos, grip, p, d_grasp, h_lift, ema, in_tr, t_ema, t_init, commit, temporal, alpha_t):
    """Validity, geometry, phase and Branch A (or the temporal EMA) for B envs.

    flat: (B, L) packed states; o: offsets of [valid, eef_pos, obj_pos, obj_rest_z, target_pos];
    ema/in_tr and t_ema/t_init: per-env memory of Branch A and of the temporal mode.
    Returns (a_phys (B, A), phase (B,) int8, geo (B, 3) [d_obj_xy, d_tgt_xy, lift] m, status (B,) int8).
    """
    b, a_dim = a_raw.shape
    a_phys = np.empty_like(a_raw)
    phase = np.full(b, -1, np.int8)
    geo = np.full((b, 3), np.nan)  # d_obj_xy, d_tgt_xy, lift (m)
    status = np.zeros(b, np.int8)
    for i in range(b):
        row = flat[i]
        finite = True
        for k in range(row.shape[0]):
            if not np.isfinite(row[k]):
                finite = False
                break
        if not row[o[0]] > 0.5:
            status[i] = INVALID_STATE
        elif not finite:
            status[i] = NONFINITE_STATE
        else:
            for k in range(a_dim):
                if not np.isfinite(a_raw[i, k]):
                    status[i] = NONFINITE_ACTION
                    break
        if status[i] != OK:
            a_phys[i] = a_raw[i]
            continue
        eef = row[o[1] : o[1] + 3]
        obj = row[o[2] : o[2] + 3]
        tgt = row[o[4] : o[4] + 3]
        d_obj = np.hypot(eef[0] - obj[0], eef[1] - obj[1])
        d_tgt = np.hypot(eef[0] - tgt[0], eef[1] - tgt[1])
        lift = obj[2] - row[o[3]]
        geo[i, 0], geo[i, 1], geo[i, 2] = d_obj, d_tgt, lift
        ph = phase_of(d_obj, d_tgt, lift, d_grasp, h_lift)  # eq. 3
        phase[i] = ph
        if temporal:
            ema_row(a_raw[i], a_phys[i], pos, alpha_t, t_ema[i], t_init[i], commit)
        else:
            branch_a_row(a_raw[i], a_phys[i], ph, eef, obj, d_tgt, pos, grip, p, ema[i], in_tr[i], commit)
    return a_phys, phase, geo, status
