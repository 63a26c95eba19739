"""Grasp: guidance toward the grasp waypoint (App. A).

    a_pos = beta (p* - p_eef) / scale + (1 - beta) a_raw_pos,   p* = p_obj + offset

p* and p_eef in metres, scale = metres per action unit, so the first term is in action units.
"""

from numba import njit

from lerobot_physvla.core.corrections.base import BETA, EEF, METRES_PER_UNIT, OBJ, OFFSET_X_M


@njit(cache=True, error_model="numpy")
def grasp_guidance(a_raw, a_phys, idx, geo, p, mem, commit):
    """Position channels blended toward p* with weight beta; gripper and rotation untouched."""
    beta, scale = p[BETA], p[METRES_PER_UNIT]
    for k in range(3):  # metres -> action units with the layout's scale
        a_phys[idx[k]] = beta * (geo[OBJ + k] + p[OFFSET_X_M + k] - geo[EEF + k]) / scale + (1.0 - beta) * a_raw[idx[k]]
