"""The `temporal` mode: a uniform EMA on the position channels in every phase (the paper's
smoothing baseline, not a Branch A correction; it shares their signature and memory row)."""

from numba import njit

from lerobot_physvla.core.corrections.base import ACTIVE, ALPHA_TEMPORAL, EMA


@njit(cache=True, error_model="numpy")
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
