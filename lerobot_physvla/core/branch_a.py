"""Branch A over B envs: validity, geometry, phase (eq. 3) and the phase's correction.

    approach   corrections.approach_veto, or corrections.rim_guide (rim_guide_m > 0; it leaves the
               gripper to the policy and the gripper rule)
    grasp      corrections.grasp_guidance, then corrections.lift_assist (lift_assist_u > 0), then
               corrections.rim_guide's rim_guide_grasp (rim_guide_into_grasp: a pull begun in approach
               goes on to the rim)
    transport  corrections.transport_smoothing
    place      corrections.place_deceleration        (eq. 5), or corrections.place_redirect
               (place_rule=redirect), or corrections.release_veto (place_rule=release_veto),
               then corrections.release_assist (release_assist_m > 0)
    (mode temporal: corrections.temporal_ema in every phase, instead of the above)

The per-env arithmetic is compiled with numba (microseconds an env-step, where small-array numpy
costs ~40); `corrector.Corrector` runs `phase_step` over B envs with per-env memory.

Compiled-cache safety: numba's on-disk cache checks a cached kernel against its own source file
only, so a cached `phase_step` would keep running the old code of a correction edited in another
file. Its cache key also hashes the function's closure (numba's `_index_key`), so `phase_step`
closes over a hash of every source file it compiles in (`SOURCE_KEY`); editing any of them
compiles it afresh. The helpers it calls are not cached themselves: they are compiled into it.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
from numba import njit

from lerobot_physvla.core.corrections.approach_veto import approach_veto
from lerobot_physvla.core.corrections.base import (
    ACTIVE, ASSIST_M, CARRIED, CARRY_REACH_M, D_OBJ_XY, D_TGT_XY, EEF, FINGERS, HIGH, HOLD, LIFT, LIFT_ASSIST_U,
    LIFT_STALL, LOW, N_GEO, OBJ, PHASE_REF_OBJECT, PLACE_RULE, RELEASE_CARRY, RIM_GUIDE_GRASP, RIM_GUIDE_M, RIM_ON,
    STALL, TGT,
)
from lerobot_physvla.core.corrections.grasp_guidance import grasp_guidance
from lerobot_physvla.core.corrections.lift_assist import lift_assist
from lerobot_physvla.core.corrections.place_deceleration import place_deceleration
from lerobot_physvla.core.corrections.place_redirect import place_redirect
from lerobot_physvla.core.corrections.release_assist import release_assist
from lerobot_physvla.core.corrections.release_veto import release_veto
from lerobot_physvla.core.corrections.rim_guide import rim_guide, rim_guide_grasp, rim_track
from lerobot_physvla.core.corrections.temporal_ema import temporal_ema
from lerobot_physvla.core.corrections.transport_smoothing import transport_smoothing
from lerobot_physvla.core.phase import APPROACH, GRASP, PLACE, TRANSPORT, phase_of
from lerobot_physvla.core.state import INVALID_STATE, NONFINITE_ACTION, NONFINITE_STATE, OK, field_offsets

_CORE = Path(__file__).resolve().parent
# every file compiled into phase_step: this one, the FSM, the state's status codes, the corrections
SOURCE_FILES = (Path(__file__).resolve(), _CORE / "phase.py", _CORE / "state.py",
                *sorted((_CORE / "corrections").glob("*.py")))


def source_key(files=SOURCE_FILES) -> int:
    """63-bit hash of the sources compiled into `phase_step` (its cache key; see module doc)."""
    h = hashlib.sha256()
    for f in files:
        h.update(f.read_bytes())
    return int.from_bytes(h.digest()[:8], "little") >> 1


SOURCE_KEY = source_key()
FINGERS_AT = field_offsets(1)["gripper"]  # a header field: the same offset in every packed state


@njit(error_model="numpy")
def branch_a_row(a_raw, a_phys, phase, idx, geo, p, mem, commit):
    """Branch A for one env: a_phys (A,) from a_raw by the phase's correction, clipped to bounds."""
    for k in range(a_raw.shape[0]):
        a_phys[k] = a_raw[k]
    if phase == APPROACH and p[RIM_GUIDE_M] > 0.0:
        rim_guide(a_raw, a_phys, idx, geo, p, mem, commit)
    elif phase == APPROACH:
        approach_veto(a_raw, a_phys, idx, geo, p, mem, commit)
    elif phase == GRASP:
        grasp_guidance(a_raw, a_phys, idx, geo, p, mem, commit)
        if p[LIFT_ASSIST_U] > 0.0:
            lift_assist(a_raw, a_phys, idx, geo, p, mem, commit)
        if p[RIM_GUIDE_GRASP] > 0.5:
            rim_guide_grasp(a_raw, a_phys, idx, geo, p, mem, commit)
    elif phase == TRANSPORT:
        transport_smoothing(a_raw, a_phys, idx, geo, p, mem, commit)
    elif phase == PLACE and p[PLACE_RULE] > 1.5:
        release_veto(a_raw, a_phys, idx, geo, p, mem, commit)
        if p[ASSIST_M] > 0.0:
            release_assist(a_raw, a_phys, idx, geo, p, mem, commit)
    elif phase == PLACE and p[PLACE_RULE] > 0.5:
        place_redirect(a_raw, a_phys, idx, geo, p, mem, commit)
    elif phase == PLACE:
        place_deceleration(a_raw, a_phys, idx, geo, p, mem, commit)
    if commit:
        mem[ACTIVE] = 1.0 if phase == TRANSPORT else 0.0
        if phase != PLACE:
            mem[HOLD] = 0.0
            mem[STALL] = 0.0
        if phase != GRASP:
            mem[LIFT_STALL] = 0.0
        if phase != APPROACH and not (phase == GRASP and p[RIM_GUIDE_GRASP] > 0.5):
            mem[RIM_ON] = 0.0
        if p[RIM_GUIDE_M] > 0.0:
            rim_track(geo, mem)
    for k in range(a_phys.shape[0]):
        a_phys[k] = min(max(a_phys[k], p[LOW]), p[HIGH])


@njit(error_model="numpy")
def carried_phase(ph, g, mem, commit):
    """release_carry: an object carried to the place phase stays in place while it is at the hand
    (within CARRY_REACH_M, 3-D), even when it is set down (its lift below h_lift would make eq. 3
    say grasp); the memory ends when the object leaves the hand."""
    dx, dy, dz = g[OBJ] - g[EEF], g[OBJ + 1] - g[EEF + 1], g[OBJ + 2] - g[EEF + 2]
    at_hand = dx * dx + dy * dy + dz * dz < CARRY_REACH_M * CARRY_REACH_M
    carried = at_hand and (ph == PLACE or mem[CARRIED] > 0.5)
    if commit:
        mem[CARRIED] = 1.0 if carried else 0.0
    return PLACE if carried and ph == GRASP else ph


@njit(error_model="numpy")
def temporal_row(a_raw, a_phys, idx, geo, p, mem, commit):
    """The temporal mode for one env: the uniform EMA in every phase (not clipped: a convex
    combination of in-bounds actions stays in bounds)."""
    for k in range(a_raw.shape[0]):
        a_phys[k] = a_raw[k]
    temporal_ema(a_raw, a_phys, idx, geo, p, mem, commit)


def _compile(key: int):
    @njit(cache=True, error_model="numpy")
    def phase_step(a_raw, flat, o, idx, p, d_grasp, h_lift, mem, commit, temporal):
        """Validity, geometry, phase and Branch A (or the temporal EMA) for B envs.

        flat: (B, L) packed states; o: offsets of [valid, eef_pos, obj_pos, obj_rest_z, target_pos];
        idx, p: see corrections/base.py; mem: (B, N_MEM) per-env memory.
        Returns (a_phys (B, A), phase (B,) int8, geo (B, 4) [d_obj_xy, d_tgt_xy, lift, height of the
        end-effector above the object's origin] m, status (B,) int8).
        """
        key  # noqa: B018 - read, so it is in the closure and hence in numba's cache key
        b, a_dim = a_raw.shape
        a_phys = np.empty_like(a_raw)
        phase = np.full(b, -1, np.int8)
        geo = np.full((b, 4), np.nan)  # d_obj_xy, d_tgt_xy, lift, eef height above the object (m)
        status = np.zeros(b, np.int8)
        g = np.empty(N_GEO)
        for i in range(b):
            row = flat[i]
            finite = True
            for k in range(row.shape[0]):
                if not np.isfinite(row[k]):
                    finite = False
                    break
            if not row[o[0]] > 0.5:
                status[i] = INVALID_STATE
            elif not finite:
                status[i] = NONFINITE_STATE
            else:
                for k in range(a_dim):
                    if not np.isfinite(a_raw[i, k]):
                        status[i] = NONFINITE_ACTION
                        break
            if status[i] != OK:
                a_phys[i] = a_raw[i]
                continue
            for k in range(3):
                g[EEF + k] = row[o[1] + k]
                g[OBJ + k] = row[o[2] + k]
                g[TGT + k] = row[o[4] + k]
            d_obj = np.hypot(g[EEF] - g[OBJ], g[EEF + 1] - g[OBJ + 1])
            lift = g[OBJ + 2] - row[o[3]]
            ref = OBJ if p[PHASE_REF_OBJECT] > 0.5 and lift > h_lift else EEF  # what d_tgt_xy measures from
            d_tgt = np.hypot(g[ref] - g[TGT], g[ref + 1] - g[TGT + 1])
            g[D_OBJ_XY], g[D_TGT_XY], g[LIFT], g[FINGERS] = d_obj, d_tgt, lift, row[FINGERS_AT]
            geo[i, 0], geo[i, 1], geo[i, 2], geo[i, 3] = d_obj, d_tgt, lift, g[EEF + 2] - g[OBJ + 2]
            ph = phase_of(d_obj, d_tgt, lift, d_grasp, h_lift)  # eq. 3
            if p[RELEASE_CARRY] > 0.5 and p[PLACE_RULE] > 1.5:
                ph = carried_phase(ph, g, mem[i], commit)
            phase[i] = ph
            if temporal:
                temporal_row(a_raw[i], a_phys[i], idx, g, p, mem[i], commit)
            else:
                branch_a_row(a_raw[i], a_phys[i], ph, idx, g, p, mem[i], commit)
        return a_phys, phase, geo, status

    return phase_step


phase_step = _compile(SOURCE_KEY)
