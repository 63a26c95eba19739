"""Grasp: the rim guide's pull, begun in the approach phase, goes on onto the rim in the grasp phase
(beyond the paper; rim_guide_into_grasp, with rim_guide_m > 0).

    while the pull is latched (rim_guide.py's RIM_ON) and the hand is further than RIM_ARRIVE_M outside
    rim_guide_m from the object's origin, low and open:  x, y as the rim guide's pull
    it never begins here; it ends within RIM_ARRIVE_M of rim_guide_m, out of the zone, or on a close.

Traced failure: docs/decisions/19-rim-guide-into-grasp.md (a hand chattering at delta_grasp).
"""

from numba import njit

from lerobot_physvla.core.corrections.base import Correction, Field, needs_authority
from lerobot_physvla.core.corrections.rim_guide import RIM_ARRIVE_M, RIM_GUIDE_M, RIM_ON, _pull, _where
from lerobot_physvla.core.phase import GRASP


@njit(error_model="numpy")
def rim_guide_grasp(a_raw, a_phys, idx, geo, p, mem, commit):
    """Grasp phase: a pull latched in the approach phase (mem[RIM_ON]) goes on onto rim_guide_m while
    the hand is further than RIM_ARRIVE_M outside it, low (RIM_HEIGHT_M) and open; x, y only."""
    if mem[RIM_ON] < 0.5:
        return
    dx, dy, rho, low_open = _where(a_raw, idx, geo, p)
    on = low_open and p[RIM_GUIDE_M] + RIM_ARRIVE_M < rho
    if on:
        _pull(a_phys, idx, geo, p, dx, dy, rho)
    if commit:
        mem[RIM_ON] = 1.0 if on else 0.0


CORRECTION = Correction("rim_guide_grasp", GRASP, 2, rim_guide_grasp, on=lambda c: c.rim_guide_into_grasp,
                        fields=(Field("rim_guide_into_grasp", bool, False, False, "the rim guide's pull goes on in the "
                                      "grasp phase until the hand reaches the rim",
                                      experimental="failed its confirmation, in no preset: docs/decisions/20-rim-guide-into-grasp-for-learned.md"),),
                        check=lambda c: _check(c))


def _check(c) -> None:
    if c.rim_guide_into_grasp and c.rim_guide_m == 0.0:
        raise ValueError("physvla: rim_guide_into_grasp goes on with the rim guide's pull; set rim_guide_m "
                         "(e.g. 0.047) or leave rim_guide_into_grasp off")
    if c.rim_guide_into_grasp:
        needs_authority(c, "rim_guide_into_grasp", (GRASP,), "leave it off")
