"""An adaptive low-pass on the executed position channels (beyond the paper; lowpass=adaptive).

The paper's foil, a uniform EMA, smooths every policy alike and lags a competent one (its
`temporal` mode takes a single-step ACT from 34 % to 0 %). This filter smooths only as much as
the policy itself is rough: per position channel it estimates the standard deviation of the
policy's step-to-step noise from its own raw actions,

    r_t     = lam r_{t-1} + (1 - lam) (a_raw_t - a_raw_{t-1})^2       (action units^2)
    sigma_t = sqrt(r_t / 2)                         (white noise of std s has E[(da)^2] = 2 s^2)
    alpha_t = alpha_max clip((sigma_t - lo) / (hi - lo), 0, 1)
    y_t     = alpha_t y_{t-1} + (1 - alpha_t) a_t                    (a_t: the blended action)

so a smooth policy (sigma below lo) is executed as it is, and a jittery one is filtered up to
alpha_max.

What is filtered (lowpass_space): `action` filters the emitted values as they are, increments on a
delta layout. Inside a closed loop (a policy that corrects toward a goal from the state it sees)
an EMA on the increments delays the correction itself: under alpha 0.6 the jitter expert's hand
reached its grasp late and the gripper closed 1.7 cm from where the unfiltered run closed it
(docs/method.md, `lowpass_space`). `target` filters the position the increment commands instead,
in action units,

    p_t = x_t / metres_per_unit + a_t        (x_t: the end effector, m; a_t: the increment)
    y_t = alpha_t y_{t-1} + (1 - alpha_t) p_t,      emitted a'_t = y_t - x_t / metres_per_unit

so the measured position enters every step unfiltered and only the policy's noise on its
target is averaged (for a goal-seeking policy the loop stays first order). On absolute layouts the
action is already a target and both are the same. The price: a move at constant commanded speed
v is executed at (1 - alpha) v (the filtered target trails the hand), which cost Fetch's 50-step
episodes their place phase. So with lowpass_speed_hi > 0 the smoothing fades with the policy's
intended speed, in the spirit of the One-Euro filter (cutoff rising with speed):

    m_t      = 0.8 m_{t-1} + 0.2 inc_t      (inc_t: the raw increment, action units; noise averages out)
    alpha'_t = alpha_t (1 - clip(|m_t| / speed_hi, 0, 1))      (|m_t| over the position channels)

It acts in the phases of `lowpass_phases`; elsewhere y follows a_t (no lag carried into a phase).
Memory per env (B, N_LP_MEM): y (3), r (3), previous raw action (3), a flag that the memory holds
a value, m (3). The gripper and rotation channels are never filtered.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from lerobot_physvla.core.state import OK

LP_Y, LP_R, LP_PREV, LP_ACTIVE, LP_SPEED = 0, 3, 6, 9, 10
N_LP_MEM = 13
ROUGH_DECAY = 0.9  # lam: the roughness estimate's memory, ~10 control steps
SPEED_DECAY = 0.8  # the intended-speed estimate's memory, ~5 control steps


@njit(cache=True, error_model="numpy")
def adaptive_lowpass(out, a_raw, phase, status, pos, mask, alpha_max, lo, hi, mem, commit, dev, flat, eef_off,
                     absolute, metres_per_unit, target, speed_hi):
    """In place on out (B, A) for the envs whose status is OK; mask (4,) int: the phases where it
    acts; dev (B,) max |out - a_raw| updated. Memory written only on commit. target: filter in
    target space (module doc): the end effector (m) is read from the packed rows flat at eef_off;
    absolute (A,) bool: channels that are targets already. speed_hi > 0: the smoothing fades out
    as the policy's intended speed (module doc) reaches speed_hi action units per step."""
    for i in range(out.shape[0]):
        if status[i] != OK:
            if commit:
                mem[i, LP_ACTIVE] = 0.0  # a passed-through step breaks the raw action's history
            continue
        active = mem[i, LP_ACTIVE] > 0.5
        acts = mask[phase[i]] != 0
        # the policy's intended speed: an EMA of its raw increments, where zero-mean noise averages out
        slow = 1.0
        if speed_hi > 0.0:
            speed2 = 0.0
            for k in range(3):
                c = pos[k]
                inc = a_raw[i, c] if not absolute[c] else (a_raw[i, c] - mem[i, LP_PREV + k] if active else 0.0)
                m = SPEED_DECAY * mem[i, LP_SPEED + k] + (1.0 - SPEED_DECAY) * inc if active else inc
                if commit:
                    mem[i, LP_SPEED + k] = m
                speed2 += m * m
            slow = max(1.0 - math.sqrt(speed2) / speed_hi, 0.0)
        for k in range(3):
            c = pos[k]
            x = a_raw[i, c]
            if active:
                d = x - mem[i, LP_PREV + k]
                r = ROUGH_DECAY * mem[i, LP_R + k] + (1.0 - ROUGH_DECAY) * d * d
            else:
                r = 0.0
            # target space: p_t = x_t / metres_per_unit + a_t (action units)
            shift = flat[i, eef_off + k] / metres_per_unit if target and not absolute[c] else 0.0
            y = out[i, c] + shift
            if acts and active:
                s = (math.sqrt(r / 2.0) - lo) / (hi - lo)
                alpha = alpha_max * min(max(s, 0.0), 1.0) * slow
                y = alpha * mem[i, LP_Y + k] + (1.0 - alpha) * y
                out[i, c] = y - shift
                dev[i] = max(dev[i], abs(out[i, c] - x))
            if commit:
                mem[i, LP_Y + k], mem[i, LP_R + k], mem[i, LP_PREV + k] = y, r, x
        if commit:
            mem[i, LP_ACTIVE] = 1.0
