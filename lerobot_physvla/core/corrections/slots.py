"""Where each correction's parameters and memory sit in the parameter vector p and an env's memory row.

Every correction file declares, at its top level, the names of its parameter slots and of its memory
slots with their sizes, as literals:

    PARAMS = ("RIM_GUIDE_M", "RIM_GUIDE_GRASP")
    MEMORY = (("RIM_TRACK", 10), ("RIM_AT", 1), ("RIM_ON", 1))

This module reads those declarations from the files' source (it imports none of them), so that the
layout does not depend on which module is imported first: p holds the shared slots (SHARED), then each
file's on-flag and PARAMS, files in name order; the memory row holds each file's MEMORY, in the same
order, then the corrector's own (SHARED_MEMORY). A correction file takes its own indices with `params(__file__)` / `memory(__file__)`; the numba
kernels see them as constants. Slot names are unique across files.
"""

from __future__ import annotations

import ast
from pathlib import Path

HERE = Path(__file__).resolve().parent
NOT_CORRECTIONS = {"__init__.py", "base.py", "slots.py"}
# the shared parameter slots, first in p: the layout's scale and bounds, the place rule's choice, the phase
# machine's reference point (PhysVLAConfig.phase_ref), the pose error the corrections tolerate (m), the
# oldest pose they act on (control steps), the layout's closed gripper command (ActionLayout.gripper_shut) and the
# poses' per-step noise the pose filter answers to (m; 0: no filter, core/pose_filter.py)
SHARED = ("METRES_PER_UNIT", "GRIPPER_OPEN", "LOW", "HIGH", "PHASE_REF_OBJECT", "POSE_ERROR_M", "POSE_MAX_AGE",
          "GRIPPER_CLOSED", "POSE_NOISE_M")
# memory of the corrector's own, after the corrections': the pose filter's (core/pose_filter.py)
SHARED_MEMORY = (("POSE_OBJ", 3), ("POSE_TGT", 3), ("POSE_EEF", 3), ("POSE_REST", 1), ("POSE_SEEN", 1), ("POSE_OUT", 2),
                 ("POSE_OPEN", 1))


def files() -> list[Path]:
    """The correction files, in the order their slots are laid out."""
    return sorted(p for p in HERE.glob("*.py") if p.name not in NOT_CORRECTIONS)


def declared(path: Path) -> tuple[tuple[str, ...], tuple[tuple[str, int], ...]]:
    """(PARAMS, MEMORY) as the file declares them (literals; missing: empty)."""
    out = {"PARAMS": (), "MEMORY": ()}
    for node in ast.parse(path.read_text()).body:
        if isinstance(node, ast.Assign) and len(node.targets) == 1 and isinstance(node.targets[0], ast.Name) \
                and node.targets[0].id in out:
            out[node.targets[0].id] = ast.literal_eval(node.value)
    return tuple(out["PARAMS"]), tuple((str(n), int(k)) for n, k in out["MEMORY"])


def _layout():
    p = {name: k for k, name in enumerate(SHARED)}
    mem, on, own_p, own_mem = {}, {}, {}, {}
    for f in files():
        names, slots = declared(f)
        on[f.stem] = len(p)
        p[f"ON_{f.stem.upper()}"] = len(p)
        own_p[f.stem] = tuple(range(len(p), len(p) + len(names)))
        for name in names:
            if name in p:
                raise RuntimeError(f"corrections/{f.name}: parameter slot {name} is declared twice")
            p[name] = len(p)
        start = sum(n for _, n in mem.values())
        own = []
        for name, size in slots:
            if name in mem:
                raise RuntimeError(f"corrections/{f.name}: memory slot {name} is declared twice")
            mem[name] = (start, size)
            own.append(start)
            start += size
        own_mem[f.stem] = tuple(own)
    start = sum(n for _, n in mem.values())
    for name, size in SHARED_MEMORY:
        if name in mem:
            raise RuntimeError(f"corrections/slots.py: memory slot {name} is declared twice")
        mem[name] = (start, size)
        start += size
    return p, {k: v[0] for k, v in mem.items()}, sum(n for _, n in mem.values()), on, own_p, own_mem


P_SLOTS, MEM_SLOTS, N_MEM, ON, _OWN_P, _OWN_MEM = _layout()
N_PARAMS = len(P_SLOTS)


def params(file: str) -> tuple[int, ...]:
    """The indices in p of the parameters a correction file declares (PARAMS), in its order."""
    return _OWN_P[Path(file).stem]


def memory(file: str) -> tuple[int, ...]:
    """The indices in the memory row of the memory slots a correction file declares (MEMORY), in its order."""
    return _OWN_MEM[Path(file).stem]
