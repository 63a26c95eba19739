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

Two more options, built from what candidates 7 and 8 cost (docs/method.md, candidate 13):

- lowpass_rough=median: the roughness from the median of the last ROBUST_WINDOW absolute second
  differences of the raw action instead of the EMA of squared first differences,

      sigma_t = median(|a_t - 2 a_{t-1} + a_{t-2}|, last 9 steps) / (0.6745 sqrt 6)    (action units)

  (white noise of std s: a second difference has std s sqrt 6, and the median of |N(0, v)| is
  0.6745 sqrt v). A step-to-step change the policy means (a chunk boundary of a chunked ACT, a
  scripted expert switching waypoints, a smooth speed-up) is one or two large values in 9 and moves
  the median little; white noise makes every value large. Measured on LIBERO init states 0-2 of
  tasks 0, 3, 7 (x, y, uncorrected): the EMA estimate is above 0.12 on 13 % of the clean expert's
  steps and 3 % of act_chunk_weak's, the median one on none; on the jitter expert 96 % / 97 %.
- lowpass_lag=compensate: a filtered target trails a constant-speed move (above); adding
  alpha / (1 - alpha) v_t to the emitted target, v_t = 0.95 v_{t-1} + 0.05 inc_t (a slower
  intended-speed EMA, action units per step), removes that steady-state lag (a hand that follows
  its target moves at v: y_t - y_{t-1} = (1 - alpha)(1 + alpha / (1 - alpha)) v = v), while the
  filter still averages the step-to-step noise. Channels already filtered as targets only (target
  space, absolute). In a simulated loop (a perfect delta controller, noise 0.3 action units,
  alpha 0.6), the mean |third difference| of the position: raw 40, trail 13, compensate with
  0.8 / 0.9 / 0.95 as the lead's decay 24 / 18 / 16 (x 10^-3 m); the slower the estimate, the
  less noise the lead carries back.

It acts in the phases of `lowpass_phases`; elsewhere y follows a_t (no lag carried into a phase).
Memory per env (B, N_LP_MEM): y (3), r (3), previous raw action (3), a flag that the memory holds
a value, m (3), the previous first difference (3), how many first differences were seen, the
lead's speed v (3), the last ROBUST_WINDOW absolute second differences per channel (3 x 9). The gripper and rotation channels
are never filtered.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from lerobot_physvla.core.state import OK

ROBUST_WINDOW = 9  # lowpass_rough=median: second differences in the median (a chunk of 10 has one boundary)
LP_Y, LP_R, LP_PREV, LP_ACTIVE, LP_SPEED, LP_PREV_D, LP_NDIFF, LP_LEAD, LP_WIN = 0, 3, 6, 9, 10, 13, 16, 17, 20
N_LP_MEM = LP_WIN + 3 * ROBUST_WINDOW
ROUGH_DECAY = 0.9  # lam: the roughness estimate's memory, ~10 control steps
SPEED_DECAY = 0.8  # the intended-speed estimate's memory, ~5 control steps
LEAD_DECAY = 0.95  # lowpass_lag=compensate: the slower speed estimate the lead follows, ~20 control steps
MEDIAN_ABS_NORMAL = 0.6745  # median of |N(0, 1)|
SQRT6 = math.sqrt(6.0)  # std of a white noise's second difference, per unit std


@njit(cache=True, error_model="numpy")
def robust_roughness(mem_row, k, d2, have, buf):
    """The noise std (action units) of channel k from the median of its last ROBUST_WINDOW absolute
    second differences in mem_row's window (the oldest replaced by |d2| when have: this step's value),
    without writing the memory; buf: scratch of ROBUST_WINDOW floats."""
    n_seen = int(mem_row[LP_NDIFF]) - 1  # second differences already in the window
    n = min(n_seen, ROBUST_WINDOW)
    m = 0
    for j in range(n):
        if have and n_seen >= ROBUST_WINDOW and j == n_seen % ROBUST_WINDOW:
            continue  # the slot this step's value overwrites
        buf[m] = mem_row[LP_WIN + k * ROBUST_WINDOW + j]
        m += 1
    if have:
        buf[m] = abs(d2)
        m += 1
    if m == 0:
        return 0.0
    return np.median(buf[:m]) / (MEDIAN_ABS_NORMAL * SQRT6)


@njit(cache=True, error_model="numpy")
def adaptive_lowpass(out, a_raw, phase, status, pos, mask, alpha_max, lo, hi, mem, commit, dev, flat, eef_off,
                     absolute, metres_per_unit, target, speed_hi, robust, compensate):
    """In place on out (B, A) for the envs whose status is OK; mask (4,) int: the phases where it
    acts; dev (B,) max |out - a_raw| updated. Memory written only on commit. target: filter in
    target space (module doc): the end effector (m) is read from the packed rows flat at eef_off;
    absolute (A,) bool: channels that are targets already. speed_hi > 0: the smoothing fades out
    as the policy's intended speed (module doc) reaches speed_hi action units per step. robust:
    the roughness from the median of second differences (lowpass_rough=median); compensate: the
    filtered target leads by alpha / (1 - alpha) of the intended speed (lowpass_lag=compensate)."""
    lead_v, buf = np.zeros(3), np.empty(ROBUST_WINDOW)  # scratch, once per call
    for i in range(out.shape[0]):
        if status[i] != OK:
            if commit:
                mem[i, LP_ACTIVE] = 0.0  # a passed-through step breaks the raw action's history
                mem[i, LP_NDIFF] = 0.0
            continue
        active = mem[i, LP_ACTIVE] > 0.5
        acts = mask[phase[i]] != 0
        # the policy's intended speed: an EMA of its raw increments, where zero-mean noise averages out
        slow = 1.0
        if speed_hi > 0.0 or compensate:
            speed2 = 0.0
            for k in range(3):
                c = pos[k]
                inc = a_raw[i, c] if not absolute[c] else (a_raw[i, c] - mem[i, LP_PREV + k] if active else 0.0)
                m = SPEED_DECAY * mem[i, LP_SPEED + k] + (1.0 - SPEED_DECAY) * inc if active else inc
                v = LEAD_DECAY * mem[i, LP_LEAD + k] + (1.0 - LEAD_DECAY) * inc if active else inc
                if commit:
                    mem[i, LP_SPEED + k], mem[i, LP_LEAD + k] = m, v
                lead_v[k] = v
                speed2 += m * m
            if speed_hi > 0.0:
                slow = max(1.0 - math.sqrt(speed2) / speed_hi, 0.0)
        have2 = active and mem[i, LP_NDIFF] >= 1.0  # a previous first difference: a second difference now
        for k in range(3):
            c = pos[k]
            x = a_raw[i, c]
            d = x - mem[i, LP_PREV + k] if active else 0.0
            d2 = d - mem[i, LP_PREV_D + k] if have2 else 0.0
            if active:
                r = ROUGH_DECAY * mem[i, LP_R + k] + (1.0 - ROUGH_DECAY) * d * d
            else:
                r = 0.0
            # target space: p_t = x_t / metres_per_unit + a_t (action units)
            is_target = target or absolute[c]
            shift = flat[i, eef_off + k] / metres_per_unit if target and not absolute[c] else 0.0
            y = out[i, c] + shift
            if acts and active:
                sigma = robust_roughness(mem[i], k, d2, have2, buf) if robust else math.sqrt(r / 2.0)
                s = (sigma - lo) / (hi - lo)
                alpha = alpha_max * min(max(s, 0.0), 1.0) * slow
                y = alpha * mem[i, LP_Y + k] + (1.0 - alpha) * y
                lead = alpha / (1.0 - alpha) * lead_v[k] if compensate and is_target else 0.0
                out[i, c] = y + lead - shift
                dev[i] = max(dev[i], abs(out[i, c] - x))
            if commit:
                mem[i, LP_Y + k], mem[i, LP_R + k], mem[i, LP_PREV + k] = y, r, x
                mem[i, LP_PREV_D + k] = d
                if have2:
                    mem[i, LP_WIN + k * ROBUST_WINDOW + (int(mem[i, LP_NDIFF]) - 1) % ROBUST_WINDOW] = abs(d2)
        if commit:
            mem[i, LP_NDIFF] = mem[i, LP_NDIFF] + 1.0 if active else 0.0
            mem[i, LP_ACTIVE] = 1.0
