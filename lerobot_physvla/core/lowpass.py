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
alpha_max. It acts in the phases of `lowpass_phases`; elsewhere y follows a_t (no lag carried
into a phase). Memory per env (B, N_LP_MEM): y (3), r (3), previous raw action (3), a flag that
the memory holds a value. The gripper and rotation channels are never filtered.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from lerobot_physvla.core.state import OK

LP_Y, LP_R, LP_PREV, LP_ACTIVE = 0, 3, 6, 9
N_LP_MEM = 10
ROUGH_DECAY = 0.9  # lam: the roughness estimate's memory, ~10 control steps


@njit(cache=True, error_model="numpy")
def adaptive_lowpass(out, a_raw, phase, status, pos, mask, alpha_max, lo, hi, mem, commit, dev):
    """In place on out (B, A) for the envs whose status is OK; mask (4,) int: the phases where it
    acts; dev (B,) max |out - a_raw| updated. Memory written only on commit."""
    for i in range(out.shape[0]):
        if status[i] != OK:
            if commit:
                mem[i, LP_ACTIVE] = 0.0  # a passed-through step breaks the raw action's history
            continue
        active = mem[i, LP_ACTIVE] > 0.5
        acts = mask[phase[i]] != 0
        for k in range(3):
            c = pos[k]
            x = a_raw[i, c]
            if active:
                d = x - mem[i, LP_PREV + k]
                r = ROUGH_DECAY * mem[i, LP_R + k] + (1.0 - ROUGH_DECAY) * d * d
            else:
                r = 0.0
            y = out[i, c]
            if acts and active:
                s = (math.sqrt(r / 2.0) - lo) / (hi - lo)
                alpha = alpha_max * min(max(s, 0.0), 1.0)
                y = alpha * mem[i, LP_Y + k] + (1.0 - alpha) * y
                out[i, c] = y
                dev[i] = max(dev[i], abs(y - x))
            if commit:
                mem[i, LP_Y + k], mem[i, LP_R + k], mem[i, LP_PREV + k] = y, r, x
        if commit:
            mem[i, LP_ACTIVE] = 1.0
