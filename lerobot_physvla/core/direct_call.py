"""Calling a compiled kernel without numba's per-call type dispatch.

A numba dispatcher, at every call, computes the numba type of each argument and looks the
signature up before it reaches the compiled code. Between two control ticks the physics step and
the policy evict the caches, and that dispatch then costs ~2-3 us of a ~16-19 us call
(eval/bench_overhead.py, cold-cache floor: `correct_stream` dispatched vs direct). The two kernels
of the control tick (the state read `pack_live_buf`, the LeRobot step's `stream_tick`) take
arguments whose types their callers fix (arrays the caller allocates, or has already checked for
dtype, dimensions and C order), so they call the compiled overload's entry point directly.
"""

from __future__ import annotations

from collections.abc import Callable

import numba


def direct_entry(dispatcher, *args) -> Callable:
    """The compiled overload of `dispatcher` for the numba types of `args` (compiled or loaded from
    numba's cache now if it is not yet), as a callable that skips numba's dispatch.

    Each call unboxes its arguments as those types without checking them: call it only with
    arguments of exactly the same dtype, number of dimensions and layout as `args`.
    """
    sig = tuple(numba.typeof(a) for a in args)
    if sig not in dispatcher.overloads:
        dispatcher.compile(sig)
    return dispatcher.overloads[sig].entry_point
