"""Approach: the premature-grasp veto (App. A). Far from the object (d_obj_xy >= delta_grasp)
no grasp can succeed, so the gripper command is set to open."""

from numba import njit

from lerobot_physvla.core.corrections.base import GRIPPER, GRIPPER_OPEN, Correction
from lerobot_physvla.core.phase import APPROACH


@njit(error_model="numpy")
def approach_veto(a_raw, a_phys, idx, geo, p, mem, commit):
    """gripper <- open (the layout's open value); other channels untouched."""
    if idx[GRIPPER] >= 0:
        a_phys[idx[GRIPPER]] = p[GRIPPER_OPEN]


CORRECTION = Correction("approach_veto", APPROACH, 0, approach_veto)
