"""The object's and the target's poses filtered over the steps their motion is known (pose_noise_m > 0).

Perception reports each pose with per-step noise (sigma per axis, m). The corrections decide by distances of
that order (a release held back beyond 2 cm of the target, a release assist after ten steps in a row within
2 cm), so with 1 cm of noise they decide by the noise (docs/decisions/22-pose-error.md). Each pose's motion
is known most of the time: the target rests, and the object rests unless the hand holds it, when it moves
with the hand, whose position is the arm's own (exact). Per env, each control step (z: the reported pose,
x: the filtered one, a = FILTER_GAIN):

    predict   x_T- = x_T                        x_O- = x_O + (p_eef - p_eef,prev)  if held, else x_O
    update    x  = x- + a (z - x-)              for each pose, unless z - x- is an outlier
    held      FINGERS_M <= opening <= widest opening seen - OPEN_MARGIN_M   (the fingers stopped on something:
              not closed on nothing, not open) and |x_O - p_eef| <= CARRY_REACH_FIXED_M (3-D)

An innovation z - x- whose 3-D length exceeds GATE_SIGMAS times its spread (sigma sqrt(1 + a / (2 - a)) per
axis) is an outlier: the filter keeps its prediction, and after OUTLIER_STEPS outliers in a row (the object
slipped, fell or was pushed: motion the model does not know) it starts that pose afresh at z. A new followed
object (its resting height changes: a sub-goal switch) starts both poses afresh, as does a new episode (the
corrector's memory is zeroed).

At rest, a pose is left with sigma sqrt(a / (2 - a)) per axis (0.23 sigma at a = 0.1, `residual_m`); what the
corrections are told grows by twice that (PhysVLAConfig.pose_error_told_m). A bias is not noise: no filter
removes it, and pose_error_m keeps telling it. With pose_noise_m = 0 (the default) nothing is filtered and
every pose reaches the corrections as reported.
"""

from __future__ import annotations

import math

from numba import njit

from lerobot_physvla.core.corrections.base import EEF, OBJ, POSE_NOISE_M, TGT
from lerobot_physvla.core.corrections.lift_assist import FINGERS_M
from lerobot_physvla.core.corrections.release_veto import CARRY_REACH_FIXED_M
from lerobot_physvla.core.corrections.slots import MEM_SLOTS

# the filter's gain per control step: a time constant of ten steps, the window over which the assists judge a
# hold (assist_steps = 10)
FILTER_GAIN = 0.1
OPEN_MARGIN_M = 0.005  # fingers this much narrower than the widest they have opened: closed (on something), m
GATE_SIGMAS = 4.0  # an innovation beyond this many spreads (3-D) is an outlier (p ~ 0.001 for noise alone)
OUTLIER_STEPS = 3  # outliers in a row that start a pose afresh, control steps

# memory (slots.SHARED_MEMORY): the filtered object and target (m, xyz), the hand at the last committed step (m),
# the followed object's resting height (m), 1.0 once a pose was seen, outliers in a row (object, target), the
# widest opening seen (m)
POSE_OBJ, POSE_TGT, POSE_EEF, POSE_REST, POSE_SEEN, POSE_OUT, POSE_OPEN = (
    MEM_SLOTS[n] for n in ("POSE_OBJ", "POSE_TGT", "POSE_EEF", "POSE_REST", "POSE_SEEN", "POSE_OUT", "POSE_OPEN"))


def residual_m(noise_m: float, gain: float = FILTER_GAIN) -> float:
    """The noise left on a pose at rest after the filter, sigma per axis (m), for per-step noise `noise_m`."""
    return noise_m * math.sqrt(gain / (2.0 - gain))


@njit(error_model="numpy")
def _update(x, z, gate2, outliers):
    """One pose's update in place (x: its prediction, 3 values); returns its outliers in a row after it."""
    n2 = 0.0
    for k in range(3):
        n2 += (z[k] - x[k]) ** 2
    if n2 > gate2:
        if outliers + 1.0 >= OUTLIER_STEPS:
            for k in range(3):
                x[k] = z[k]
            return 0.0
        return outliers + 1.0
    for k in range(3):
        x[k] += FILTER_GAIN * (z[k] - x[k])
    return 0.0


@njit(error_model="numpy")
def pose_filter(row, o_eef, o_obj, o_rest, o_tgt, fingers, p, mem, commit, g):
    """g[OBJ:OBJ+3], g[TGT:TGT+3] <- the filtered object and target of one env (module doc) from its packed state
    row (offsets of eef_pos, obj_pos, obj_rest_z, target_pos; fingers: the gripper's opening, m); mem is written
    only when commit is True (a chunk's look-ahead steps read the filter and leave it as it was)."""
    sigma = p[POSE_NOISE_M]
    spread2 = sigma * sigma * (1.0 + FILTER_GAIN / (2.0 - FILTER_GAIN))
    gate2 = GATE_SIGMAS * GATE_SIGMAS * 3.0 * spread2  # 3-D: GATE_SIGMAS spreads on each of 3 axes
    z_o, z_t = row[o_obj : o_obj + 3], row[o_tgt : o_tgt + 3]
    rest = row[o_rest]
    widest = max(mem[POSE_OPEN], fingers)
    x_o, x_t = g[OBJ : OBJ + 3], g[TGT : TGT + 3]
    if mem[POSE_SEEN] < 0.5 or rest != mem[POSE_REST]:  # a new episode or a new followed object: start afresh
        out_o = out_t = 0.0
        for k in range(3):
            x_o[k], x_t[k] = z_o[k], z_t[k]
    else:
        reach2 = 0.0
        for k in range(3):
            x_o[k], x_t[k] = mem[POSE_OBJ + k], mem[POSE_TGT + k]
            reach2 += (x_o[k] - row[o_eef + k]) ** 2
        held = FINGERS_M <= fingers <= widest - OPEN_MARGIN_M and reach2 <= CARRY_REACH_FIXED_M * CARRY_REACH_FIXED_M
        if held:  # the object moves with the hand
            for k in range(3):
                x_o[k] += row[o_eef + k] - mem[POSE_EEF + k]
        out_o = _update(x_o, z_o, gate2, mem[POSE_OUT])
        out_t = _update(x_t, z_t, gate2, mem[POSE_OUT + 1])
    if commit:
        for k in range(3):
            mem[POSE_OBJ + k], mem[POSE_TGT + k], mem[POSE_EEF + k] = x_o[k], x_t[k], row[o_eef + k]
        mem[POSE_REST], mem[POSE_SEEN], mem[POSE_OPEN] = rest, 1.0, widest
        mem[POSE_OUT], mem[POSE_OUT + 1] = out_o, out_t
