"""Place: the deceleration ramp of eq. (5).

    a_pos = min(1, d_tgt_xy / d_thresh) a_raw_pos         (d_tgt_xy, d_thresh in metres)
"""

from numba import njit

from lerobot_physvla.core.corrections import slots
from lerobot_physvla.core.corrections.base import D_TGT_XY, Correction, Field
from lerobot_physvla.core.phase import PLACE

PARAMS = ("D_THRESH_M",)  # the deceleration's scale, m
(D_THRESH_M,) = slots.params(__file__)


@njit(error_model="numpy")
def place_deceleration(a_raw, a_phys, idx, geo, p, mem, commit):
    """Position channels scaled down near the target; gripper and rotation untouched."""
    ramp = min(1.0, geo[D_TGT_XY] / p[D_THRESH_M])  # eq. 5
    for k in range(3):
        a_phys[idx[k]] = ramp * a_raw[idx[k]]


CORRECTION = Correction("place_deceleration", PLACE, 0, place_deceleration,
                        values={"D_THRESH_M": lambda c, lay: c.d_thresh_m}, on=lambda c: c.place_rule == "decelerate",
                        fields=(Field("d_thresh_m", float, 0.08, 0.08, "the deceleration's scale (eq. 5), m"),),
                        check=lambda c: _positive(c.d_thresh_m))


def _positive(d) -> None:
    if not d > 0:
        raise ValueError(f"physvla: d_thresh_m must be > 0, got {d}")
