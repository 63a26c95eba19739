"""Place: redirection of the held object over the target (beyond the paper; place_rule=redirect).

    a_xy = gain (p_tgt_xy - p_obj_xy) / scale          (positions in metres, scale = m per unit)

Where eq. (5) only slows a biased approach down, this steers it: the horizontal channels become
a proportional move that brings the held object's centre (not the hand's: a rim grasp holds the
object centimetres off the hand) over the target's. The vertical channel and the gripper stay
the policy's, so it still decides when to lower and release.
"""

from numba import njit

from lerobot_physvla.core.corrections.base import METRES_PER_UNIT, OBJ, REDIRECT_GAIN, TGT


@njit(cache=True, error_model="numpy")
def place_redirect(a_raw, a_phys, idx, geo, p, mem, commit):
    """x, y channels <- gain (target - object) / scale; z, rotation and gripper untouched."""
    gain, scale = p[REDIRECT_GAIN], p[METRES_PER_UNIT]
    for k in range(2):
        a_phys[idx[k]] = gain * (geo[TGT + k] - geo[OBJ + k]) / scale
