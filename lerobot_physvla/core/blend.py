"""The capped blender (eq. 2) and the safety net on every emitted action, per env (numba).

`blend` mixes the policy's action with the corrected candidate, a = (1 - c) a_raw + c a_cand
(c: the phase's authority, `PhysVLAConfig.caps`), applies the gripper rule and clips to the
layout's bounds; `guard` is the do-no-harm net of
`corrector.py`'s contract: rows that could not be corrected get the policy's action clipped
to the bounds, or the layout's hold action where it is not finite.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from lerobot_physvla.core.phase import APPROACH, GRASP
from lerobot_physvla.core.state import GUARD_CLIPPED, GUARD_HELD, NONFINITE_OUTPUT, OK


@njit(cache=True, error_model="numpy")
def blend(a_raw, a_cand, phase, status, caps, grip, gripper_open, veto, geo, low, high, last, has_last, hold_tol):
    """Eq. 2 with the gripper rule and clipping for every env whose status is OK; an env whose
    result is not finite gets status NONFINITE_OUTPUT. Rows of other envs are left for `_guard`.

    caps (4,): the authority c per phase. veto: the gripper rule `veto` sets the gripper to open
    in full (never blended) where no grasp can close on the object; geo (B, 7) [d_obj_xy, d_tgt_xy,
    lift, eef height above the object's origin, veto height, veto reach] (m, the last two each env's own:
    core/geometry.py), then 1.0 where the policy's close is timed to the hand's descent onto the object
    (corrections/approach_veto.py timed_close) says where that is: in the approach phase, wherever the hand is reach
    or more from the object horizontally or more than height above it (reach 0: everywhere in approach, the paper);
    in the grasp phase, where it is more than height above it (height 0: never), unless the close is timed.
    veto: 0 off, 1 on, 2 on but never opening a gripper that holds: one whose last executed command (last (B, A),
    has_last (B,)) lies more than hold_tol from open (ActionLayout.gripper_hold_tol: half the action range,
    or of the open-to-closed span where the layout names its closed command).
    """
    out = np.empty_like(a_raw)
    dev = np.zeros(a_raw.shape[0])
    for i in range(a_raw.shape[0]):
        if status[i] == OK:
            finite = True
            cap = caps[phase[i]]
            veto_height, veto_reach = geo[i, 4], geo[i, 5]
            above = veto_height > 0.0 and geo[i, 3] > veto_height
            vetoed = veto > 0 and ((phase[i] == APPROACH and (veto_reach <= 0.0 or geo[i, 0] >= veto_reach or above))
                                   or (phase[i] == GRASP and above and not geo[i, 6] > 0.5))
            if vetoed and veto == 2 and grip >= 0 and has_last[i]:
                vetoed = abs(last[i, grip] - gripper_open) <= hold_tol  # holding: leave it closed
            for k in range(a_raw.shape[1]):
                v = (1.0 - cap) * a_raw[i, k] + cap * a_cand[i, k]
                if vetoed and k == grip:
                    v = gripper_open
                v = min(max(v, low), high)
                finite = finite and np.isfinite(v)
                out[i, k] = v
                dev[i] = max(dev[i], abs(v - a_raw[i, k]))
            if finite:
                continue
            status[i] = NONFINITE_OUTPUT
            dev[i] = 0.0
    return out, dev


@njit(cache=True, error_model="numpy")
def guard(out, a_raw, status, every, absolute, hold0, low, high, last, has_last, commit):
    """The safety net on emitted actions (see the module's contract), in place on out (B, A).

    Rows with status != OK (every row if `every`) get a_raw clipped to [low, high] if it is
    finite, else the hold action: 0 where absolute[k] is False, else last[i, k] (or hold0[k]
    before this env emitted anything). Corrected rows are clipped to [low, high] too (a step after
    the blend, such as the low-pass in target space, may leave them; not counted as a clip of the
    policy's action). On commit, out becomes the env's `last`.
    Returns (B,) int8 GUARD_* codes.
    """
    b, a_dim = out.shape
    guard = np.zeros(b, np.int8)
    for i in range(b):
        if every or status[i] != OK:
            finite = True
            for k in range(a_dim):
                if not np.isfinite(a_raw[i, k]):
                    finite = False
                    break
            if finite:
                for k in range(a_dim):
                    v = min(max(a_raw[i, k], low), high)
                    if v != a_raw[i, k]:
                        guard[i] = GUARD_CLIPPED
                    out[i, k] = v
            else:
                guard[i] = GUARD_HELD
                for k in range(a_dim):
                    if absolute[k]:
                        out[i, k] = last[i, k] if has_last[i] else hold0[k]
                    else:
                        out[i, k] = 0.0
        else:
            for k in range(a_dim):
                out[i, k] = min(max(out[i, k], low), high)
        if commit:
            for k in range(a_dim):
                last[i, k] = out[i, k]
            has_last[i] = True
    return guard
