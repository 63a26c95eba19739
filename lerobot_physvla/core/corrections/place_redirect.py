"""Place: redirection of the held object over the target (beyond the paper; place_rule=redirect).

    e = p_tgt_xy - p_obj_xy,  n = |e|                    (metres)
    a_xy = a_raw_xy                                     if n <= tol
    a_xy = gain (1 - tol / n) e / scale                 otherwise (scale = m per unit)

Where eq. (5) only slows a biased approach down, this steers it: the horizontal channels become
a proportional move that brings the held object's centre (not the hand's: a rim grasp holds the
object centimetres off the hand) to within `tol` of the target's. Inside that tolerance the
policy keeps its own x, y: a learned policy releases where it means to, and a redirection that
pinned the object on the target's exact centre held it a centimetre from that point, where it
waited for the whole episode (docs/decisions/default-v2.md). The vertical channel and the
gripper stay the policy's, so it still decides when to lower and release.
"""

from numba import njit

from lerobot_physvla.core.corrections import slots
from lerobot_physvla.core.corrections.base import METRES_PER_UNIT, OBJ, POSE_ERROR_M, TGT, Correction
from lerobot_physvla.core.phase import PLACE

PARAMS = ("PLACE_GAIN", "PLACE_TOL_M")  # the steering gain (action units per unit of error); its tolerance, m
PLACE_GAIN, PLACE_TOL_M = slots.params(__file__)


@njit(error_model="numpy")
def steer(geo, p, tol):
    """(k, ex, ey): the steering move is a_xy = k (ex, ey), with (ex, ey) = target - object (m) and
    k = gain (1 - tol / n) / scale beyond tol (m; n = |(ex, ey)|), k = 0 within it."""
    ex, ey = geo[TGT] - geo[OBJ], geo[TGT + 1] - geo[OBJ + 1]
    n = (ex * ex + ey * ey) ** 0.5
    k = p[PLACE_GAIN] * (1.0 - tol / n) / p[METRES_PER_UNIT] if n > tol else 0.0
    return k, ex, ey


@njit(error_model="numpy")
def place_redirect(a_raw, a_phys, idx, geo, p, mem, commit):
    """x, y channels <- k (target - object) beyond tol (`steer`); z, rotation and gripper, and x, y
    within tol: the policy's (a_phys starts as a_raw)."""
    k, ex, ey = steer(geo, p, p[PLACE_TOL_M] + p[POSE_ERROR_M])  # within tol + the pose error: left alone
    if k > 0.0:
        a_phys[idx[0]] = k * ex
        a_phys[idx[1]] = k * ey


CORRECTION = Correction("place_redirect", PLACE, 0, place_redirect, values={
    "PLACE_GAIN": lambda c, lay: c.place_gain, "PLACE_TOL_M": lambda c, lay: c.place_tol_m},
    on=lambda c: c.place_rule == "redirect",
    pose="steers only the object's error beyond place_tol_m + pose_error_m")  # its fields: core/config.py's place group

