"""Transport: lift bias and EMA on the position channels (App. A).

    a_pos <- alpha a_pos_prev + (1 - alpha) (a_raw_pos + dz+ / scale e_z)

The EMA starts from the current (biased) action on the first transport step.
"""

from numba import njit

from lerobot_physvla.core.corrections import slots
from lerobot_physvla.core.corrections.base import Correction, Field, unit_interval
from lerobot_physvla.core.phase import TRANSPORT

PARAMS = ("ALPHA_TRANSPORT", "LIFT_BIAS_U")  # the EMA's factor; the lift bias, action units
MEMORY = (("TRANSPORT_EMA", 3), ("TRANSPORT_ACTIVE", 1))  # the EMA (x, y, z, action units); 1.0: it holds a value
ALPHA_TRANSPORT, LIFT_BIAS_U = slots.params(__file__)
EMA, ACTIVE = slots.memory(__file__)


@njit(error_model="numpy")
def transport_smoothing(a_raw, a_phys, idx, geo, p, mem, commit):
    """Position channels: EMA of (raw + lift bias on z); memory updated only if commit."""
    alpha, lift_u = p[ALPHA_TRANSPORT], p[LIFT_BIAS_U]
    first = not mem[ACTIVE] > 0.5
    for k in range(3):
        x = a_raw[idx[k]] + (lift_u if k == 2 else 0.0)
        prev = x if first else mem[EMA + k]
        e = alpha * prev + (1.0 - alpha) * x
        a_phys[idx[k]] = e
        if commit:
            mem[EMA + k] = e


@njit(error_model="numpy")
def transport_commit(phase, geo, p, mem):
    """The EMA holds a value only while the previous committed step was in transport."""
    mem[ACTIVE] = 1.0 if phase == TRANSPORT else 0.0


CORRECTION = Correction("transport_smoothing", TRANSPORT, 0, transport_smoothing, values={
    "ALPHA_TRANSPORT": lambda c, lay: c.alpha_transport, "LIFT_BIAS_U": lambda c, lay: c.lift_bias_m / lay.metres_per_unit},
    commit=transport_commit,
    fields=(Field("lift_bias_m", float, 0.0, 0.02, "the vertical lift bias added to the z command, m"),
            Field("alpha_transport", float, 0.0, 0.92, "the EMA's factor on the position channels")),
    check=lambda c: unit_interval(c, "alpha_transport"))
