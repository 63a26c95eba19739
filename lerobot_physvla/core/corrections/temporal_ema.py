"""The `temporal` mode: a uniform EMA on the position channels in every phase (the paper's
smoothing baseline, not a Branch A correction; it shares their signature and memory row)."""

from numba import njit

from lerobot_physvla.core.corrections import slots
from lerobot_physvla.core.corrections.base import Correction, Field, unit_interval

PARAMS = ("ALPHA_TEMPORAL",)  # the EMA's factor
MEMORY = (("TEMPORAL_EMA", 3), ("TEMPORAL_ACTIVE", 1))  # the EMA (x, y, z, action units); 1.0: it holds a value
(ALPHA_TEMPORAL,) = slots.params(__file__)
EMA, ACTIVE = slots.memory(__file__)


@njit(error_model="numpy")
def temporal_ema(a_raw, a_phys, idx, geo, p, mem, commit):
    """a_pos <- alpha_temporal a_pos_prev + (1 - alpha_temporal) a_raw_pos; memory updated if commit."""
    alpha = p[ALPHA_TEMPORAL]
    for k in range(3):
        x = a_raw[idx[k]]
        prev = mem[EMA + k] if mem[ACTIVE] > 0.5 else x
        e = alpha * prev + (1.0 - alpha) * x
        a_phys[idx[k]] = e
        if commit:
            mem[EMA + k] = e
    if commit:
        mem[ACTIVE] = 1.0


# the temporal mode's EMA: in every phase of that mode, instead of Branch A (core/branch_a.py temporal_row)
CORRECTION = Correction("temporal_ema", None, 0, temporal_ema, values={"ALPHA_TEMPORAL": lambda c, lay: c.alpha_temporal},
                        on=lambda c: c.mode == "temporal",
                        fields=(Field("alpha_temporal", float, 0.85, 0.85, "the temporal mode's EMA factor"),),
                        check=lambda c: unit_interval(c, "alpha_temporal"))
