"""Place: redirection of the held object over the target (beyond the paper; place_rule=redirect).

    e = p_tgt_xy - p_obj_xy,  n = |e|                    (metres)
    a_xy = a_raw_xy                                     if n <= tol
    a_xy = gain (1 - tol / n) e / scale                 otherwise (scale = m per unit)

Where eq. (5) only slows a biased approach down, this steers it: the horizontal channels become
a proportional move that brings the held object's centre (not the hand's: a rim grasp holds the
object centimetres off the hand) to within `tol` of the target's. Inside that tolerance the
policy keeps its own x, y: a learned policy releases where it means to, and a redirection that
pinned the object on the target's exact centre held it a centimetre from that point, where it
waited for the whole episode (eval/results/efficacy section 7). The vertical channel and the
gripper stay the policy's, so it still decides when to lower and release.
"""

from numba import njit

from lerobot_physvla.core.corrections.base import METRES_PER_UNIT, OBJ, REDIRECT_GAIN, REDIRECT_TOL_M, TGT


@njit(cache=True, error_model="numpy")
def place_redirect(a_raw, a_phys, idx, geo, p, mem, commit):
    """x, y channels <- gain (1 - tol / n) (target - object) / scale beyond tol; z, rotation and
    gripper untouched."""
    gain, scale, tol = p[REDIRECT_GAIN], p[METRES_PER_UNIT], p[REDIRECT_TOL_M]
    ex, ey = geo[TGT] - geo[OBJ], geo[TGT + 1] - geo[OBJ + 1]
    n = (ex * ex + ey * ey) ** 0.5
    if n <= tol:
        return  # within tolerance: the policy's own x, y (a_phys starts as a_raw)
    k = gain * (1.0 - tol / n) / scale
    a_phys[idx[0]] = k * ex
    a_phys[idx[1]] = k * ey
