"""Grasp: guidance toward the grasp waypoint (App. A).

    a_pos = beta (p* - p_eef) / scale + (1 - beta) a_raw_pos,   p* = p_obj + offset

p* and p_eef in metres, scale = metres per action unit, so the first term is in action units.
Pose error (pose_error_m = e): p* comes from the object's pose, so beta is scaled by max(0, 1 - e / delta_grasp):
the blend toward a point that may be e off fades out as e nears the grasp envelope.
"""

from numba import njit

from lerobot_physvla.core.corrections import slots
from lerobot_physvla.core.corrections.base import EEF, METRES_PER_UNIT, OBJ, Correction, Field, unit_interval
from lerobot_physvla.core.phase import GRASP

PARAMS = ("BETA", "OFFSET_X_M", "OFFSET_Y_M", "OFFSET_Z_M")  # the blend weight; the grasp point's offset, m
BETA, OFFSET_X_M, OFFSET_Y_M, OFFSET_Z_M = slots.params(__file__)


@njit(error_model="numpy")
def grasp_guidance(a_raw, a_phys, idx, geo, p, mem, commit):
    """Position channels blended toward p* with weight beta; gripper and rotation untouched."""
    beta, scale = p[BETA], p[METRES_PER_UNIT]
    for k in range(3):  # metres -> action units with the layout's scale
        a_phys[idx[k]] = beta * (geo[OBJ + k] + p[OFFSET_X_M + k] - geo[EEF + k]) / scale + (1.0 - beta) * a_raw[idx[k]]


CORRECTION = Correction("grasp_guidance", GRASP, 0, grasp_guidance, values={
    "BETA": lambda c, lay: c.beta * max(0.0, 1.0 - c.pose_error_told_m / c.delta_grasp_m), "OFFSET_X_M": lambda c, lay: c.grasp_offset_m[0],
    "OFFSET_Y_M": lambda c, lay: c.grasp_offset_m[1], "OFFSET_Z_M": lambda c, lay: c.grasp_offset_m[2]},
    fields=(Field("beta", float, 0.0, 0.5, "the blend's weight toward the grasp point (0: the policy's action)"),
            Field("grasp_offset_m", tuple[float, float, float], (0.0, 0.0, 0.0), (0.0, 0.0, 0.0),
                  "the grasp point p* = the object's position + this offset, m (world frame)")),
    check=lambda c: (unit_interval(c, "beta"), _three(c.grasp_offset_m)),
    pose="blends toward a point from the object's pose: beta x max(0, 1 - pose_error_m / delta_grasp_m)")


def _three(offset) -> None:
    if len(offset) != 3:
        raise ValueError(f"physvla: grasp_offset_m needs 3 values, got {offset}")
