"""Transport: lift bias and EMA on the position channels (App. A).

    a_pos <- alpha a_pos_prev + (1 - alpha) (a_raw_pos + dz+ / scale e_z)

The EMA starts from the current (biased) action on the first transport step.
"""

from numba import njit

from lerobot_physvla.core.corrections.base import ACTIVE, ALPHA_TRANSPORT, EMA, LIFT_BIAS_U


@njit(cache=True, error_model="numpy")
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
