"""Place: a veto of releases that would miss the target (beyond the paper; place_rule=release_veto).

    e = p_tgt_xy - p_obj_xy,  n = |e|                          (metres)
    while the policy commands open and n > tol:
        gripper <- closed;  a_xy = gain (1 - tol / n) e / scale    (scale = m per unit)

The place redirection (`place_redirect.py`) steers the held object for the whole place phase and
so takes the horizontal channels from a policy that is still moving to its own release point; a
learned policy then waits there for the rest of the episode (eval/results/efficacy section 7).
This correction leaves the policy alone until the one moment its error is certain to matter: it
opens the gripper with the held object's centre more than `tol` from the target's. Only then is
the release held back (gripper closed) and the object steered to within `tol`, where the
policy's own open command goes through. The vertical channel stays the policy's throughout. A
hold lasts at most `hold_steps` control steps in a row (the target may be out of reach), after
which the policy's command goes through as it is.
"""

from numba import njit

from lerobot_physvla.core.corrections.base import GRIPPER, GRIPPER_OPEN, HOLD, HOLD_STEPS
from lerobot_physvla.core.corrections.place_redirect import steer


@njit(cache=True, error_model="numpy")
def release_veto(a_raw, a_phys, idx, geo, p, mem, commit):
    """Gripper held closed and x, y steered toward the target while the policy opens off target."""
    g = idx[GRIPPER]
    miss = False  # the policy opens with the object's centre beyond tol of the target's
    if g >= 0 and a_raw[g] * p[GRIPPER_OPEN] > 0.0:
        k, ex, ey = steer(geo, p)
        miss = k > 0.0
        if miss and mem[HOLD] < p[HOLD_STEPS]:
            a_phys[g] = -p[GRIPPER_OPEN]
            a_phys[idx[0]] = k * ex
            a_phys[idx[1]] = k * ey
    if commit:  # count held (or yielded) steps in a row; anything else starts over
        mem[HOLD] = min(mem[HOLD] + 1.0, p[HOLD_STEPS]) if miss else 0.0
