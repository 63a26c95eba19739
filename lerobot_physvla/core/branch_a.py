"""Branch A over B envs: validity, geometry (the poses filtered where pose_noise_m > 0: core/pose_filter.py), phase
(eq. 3) and the phase's corrections.

The per-phase dispatch (`branch_a_row`) is assembled from the corrections' declarations
(corrections/__init__.py CORRECTIONS): in each phase, every correction of that phase that the
configuration turns on (its on-flag in p), in their declared order, each on the candidate the earlier
ones left; on a committed step, every turned-on correction's memory upkeep; then the clip to the bounds.
With the shipped declarations:

    approach   rim_guide where it is on (it replaces approach_veto), else approach_veto; then centre_guide_approach
    grasp      grasp_guidance, then lift_assist, then rim_guide_grasp, then centre_guide (each where it is on)
    transport  transport_smoothing, then approach_pull_carry, carry_to_target (each where it is on)
    place      place_deceleration (eq. 5), place_redirect or release_veto (place_rule), then release_assist, then
               carry_to_target_place
    (mode temporal: temporal_ema in every phase, instead of the above)

The per-env arithmetic is compiled with numba (microseconds an env-step, where small-array numpy
costs ~40); `corrector.Corrector` runs `phase_step` over B envs with per-env memory.

Compiled-cache safety: numba's on-disk cache checks a cached kernel against its own source file
only, so a cached `phase_step` would keep running the old code of a correction edited in another
file. Its cache key also hashes the function's closure (numba's `_index_key`), so `phase_step`
closes over a hash of every source file it compiles in and of the assembled dispatch's source
(`SOURCE_KEY`); editing any of them compiles it afresh. The helpers it calls (the correction kernels, core/geometry.py) are
not cached themselves: they are compiled into it, and their slot indices come from every correction file's
declarations, which a cache keyed on their own file alone would not see change.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
from numba import njit

from lerobot_physvla.core.corrections import CORRECTIONS, slots
from lerobot_physvla.core.corrections.approach_veto import MEETS, MEETS_ONSET, held_to_top, timed_close
from lerobot_physvla.core.corrections.base import (D_OBJ_XY, D_TGT_XY, EEF, FINGERS, HIGH, LIFT, LOW, N_GEO, OBJ,
                                                   PHASE_REF_OBJECT, POSE_MAX_AGE, POSE_NOISE_M, TGT)
from lerobot_physvla.core.corrections.release_veto import RELEASE_CARRY, carried_phase
from lerobot_physvla.core.corrections.temporal_ema import temporal_ema
from lerobot_physvla.core.geometry import N_SCENE, measured, scene_distances
from lerobot_physvla.core.phase import PHASE_NAMES, phase_of
from lerobot_physvla.core.pose_filter import pose_filter
from lerobot_physvla.core.state import (INVALID_STATE, MISSING_POSE, NONFINITE_ACTION, NONFINITE_STATE, OK,
                                       STALE_POSE, UNSUPPORTED_GOAL, field_offsets)

_CORE = Path(__file__).resolve().parent
# every file compiled into phase_step: this one, the FSM, the state's status codes, the scene's distances, the pose
# filter, the corrections
SOURCE_FILES = (Path(__file__).resolve(), _CORE / "phase.py", _CORE / "state.py", _CORE / "geometry.py",
                _CORE / "pose_filter.py", *sorted((_CORE / "corrections").glob("*.py")))
ON_RELEASE_VETO = slots.ON["release_veto"]


def dispatch_source(corrections=CORRECTIONS) -> str:
    """The source of `branch_a_row`, assembled from the corrections' declarations."""
    lines = ["def branch_a_row(a_raw, a_phys, phase, idx, geo, p, mem, commit):",
             "    for k in range(a_raw.shape[0]):",
             "        a_phys[k] = a_raw[k]"]
    first = True
    for ph in range(len(PHASE_NAMES)):
        mine = sorted((c for c in corrections if c.phase == ph), key=lambda c: c.order)
        if not mine:
            continue
        lines.append(f"    {'if' if first else 'elif'} phase == {ph}:  # {PHASE_NAMES[ph]}")
        first = False
        for c in mine:
            lines += [f"        if p[{slots.ON[c.name]}] > 0.5:",
                      f"            {c.name}(a_raw, a_phys, idx, geo, p, mem, commit)"]
    hooks = [c for c in corrections if c.commit is not None]
    if hooks:
        lines.append("    if commit:")
        for c in hooks:
            lines += [f"        if p[{slots.ON[c.name]}] > 0.5:",
                      f"            {c.name}_commit(phase, geo, p, mem)"]
    lines += ["    for k in range(a_phys.shape[0]):",
              f"        a_phys[k] = min(max(a_phys[k], p[{LOW}]), p[{HIGH}])"]
    return "\n".join(lines) + "\n"


def _assemble(corrections=CORRECTIONS):
    """`branch_a_row` compiled from dispatch_source: Branch A for one env, a_phys (A,) from a_raw by the
    phase's corrections, clipped to bounds."""
    namespace = {c.name: c.kernel for c in corrections} | {f"{c.name}_commit": c.commit for c in corrections
                                                             if c.commit is not None}
    exec(compile(dispatch_source(corrections), "<corrections dispatch>", "exec"), namespace)  # noqa: S102
    return njit(error_model="numpy")(namespace["branch_a_row"])


def source_key(files=SOURCE_FILES, extra: str = "") -> int:
    """63-bit hash of the sources compiled into `phase_step` (its cache key; see module doc)."""
    h = hashlib.sha256()
    for f in files:
        h.update(f.read_bytes())
    h.update(extra.encode())
    return int.from_bytes(h.digest()[:8], "little") >> 1


DISPATCH_SOURCE = dispatch_source()
SOURCE_KEY = source_key(extra=DISPATCH_SOURCE)
FINGERS_AT = field_offsets(1)["gripper"]  # a header field: the same offset in every packed state
branch_a_row = _assemble()


@njit(error_model="numpy")
def temporal_row(a_raw, a_phys, idx, geo, p, mem, commit):
    """The temporal mode for one env: the uniform EMA in every phase (not clipped: a convex
    combination of in-bounds actions stays in bounds)."""
    for k in range(a_raw.shape[0]):
        a_phys[k] = a_raw[k]
    temporal_ema(a_raw, a_phys, idx, geo, p, mem, commit)


def _compile(key: int):
    @njit(cache=True, error_model="numpy")
    def phase_step(a_raw, flat, o, idx, p, d_grasp, h_lift, veto, mem, commit, temporal):
        """Validity, geometry, phase and Branch A (or the temporal EMA) for B envs.

        flat: (B, L) packed states; o: offsets of [valid, eef_pos, obj_pos, obj_rest_z, target_pos, pose_age, scene]
        (scene -1: the distances as configured), then of [dt, qdot, M, bias, tau, J_pos] and the joint count n
        (tick.py's ip[0:14]; the hand's vertical velocity: J_pos's z row times qdot); idx, p: see
        corrections/base.py; d_grasp, h_lift (m): eq. 3's;
        veto (4,): the gripper veto's [height, reach] (m) and the configuration's (core/geometry.py);
        mem: (B, N_MEM) per-env memory.
        Returns (a_phys (B, A), phase (B,) int8, geo (B, 7) [d_obj_xy, d_tgt_xy, lift, height of the
        end-effector above the object's origin, veto height, veto reach] m and 1.0 where the policy's close is timed
        to the hand's descent onto the object (the height veto leaves it alone: corrections/approach_veto.py), else
        0.0, status (B,) int8).
        """
        key  # noqa: B018 - read, so it is in the closure and hence in numba's cache key
        b, a_dim = a_raw.shape
        a_phys = np.empty_like(a_raw)
        phase = np.full(b, -1, np.int8)
        geo = np.full((b, 7), np.nan)  # d_obj_xy, d_tgt_xy, lift, eef height above the object, veto height, reach (m),
        # 1.0 where the policy's close is timed to the hand's descent (corrections/approach_veto.py timed_close)
        status = np.zeros(b, np.int8)
        g = np.empty(N_GEO)
        pe = np.empty_like(p)  # an env's parameters with its scene's distances (core/geometry.py)
        veto_i = np.empty(2)
        for i in range(b):
            row = flat[i]
            finite, pose_finite = True, True  # every field but the pose and the scene; the pose (obj_pos, obj_rest_z,
            for k in range(o[5] + 1):  # target_pos); the scene may be unmeasured (NaN), which keeps the fixed distances
                if not np.isfinite(row[k]):
                    if o[2] <= k < o[2] + 4 or o[4] <= k < o[4] + 3:  # obj_pos and obj_rest_z lie together
                        pose_finite = False
                    else:
                        finite = False
                        break
            if not row[o[0]] > 0.5:  # valid: 0 not read, -1 a task outside the model
                status[i] = UNSUPPORTED_GOAL if row[o[0]] < -0.5 else INVALID_STATE
            elif not finite:
                status[i] = NONFINITE_STATE
            elif not pose_finite:  # the state source has no pose of the object or the target
                status[i] = MISSING_POSE
            elif row[o[5]] > p[POSE_MAX_AGE]:  # pose_age: older than the bound
                status[i] = STALE_POSE
            else:
                for k in range(a_dim):
                    if not np.isfinite(a_raw[i, k]):
                        status[i] = NONFINITE_ACTION
                        break
            if status[i] != OK:
                a_phys[i] = a_raw[i]
                continue
            q, dg = p, d_grasp
            veto_i[0], veto_i[1] = veto[0], veto[1]
            on_scene = measured(row, o[6])
            if on_scene:  # the distances of this env's scene
                dg = scene_distances(row, o[6], p, pe, veto[2:4], veto_i)
                q = pe
            for k in range(3):
                g[EEF + k] = row[o[1] + k]
                g[OBJ + k] = row[o[2] + k]
                g[TGT + k] = row[o[4] + k]
            if p[POSE_NOISE_M] > 0.0:  # noisy poses: filtered over the steps their motion is known (pose_filter.py)
                pose_filter(row, o[1], o[2], o[3], o[4], row[FINGERS_AT], p, mem[i], commit, g)
            d_obj = np.hypot(g[EEF] - g[OBJ], g[EEF + 1] - g[OBJ + 1])
            lift = g[OBJ + 2] - row[o[3]]
            ref = OBJ if q[PHASE_REF_OBJECT] > 0.5 and lift > h_lift else EEF  # what d_tgt_xy measures from
            d_tgt = np.hypot(g[ref] - g[TGT], g[ref + 1] - g[TGT + 1])
            g[D_OBJ_XY], g[D_TGT_XY], g[LIFT], g[FINGERS] = d_obj, d_tgt, lift, row[FINGERS_AT]
            geo[i, 0], geo[i, 1], geo[i, 2], geo[i, 3] = d_obj, d_tgt, lift, g[EEF + 2] - g[OBJ + 2]
            geo[i, 4], geo[i, 5] = veto_i[0], veto_i[1]
            ph = phase_of(d_obj, d_tgt, lift, dg, h_lift)  # eq. 3
            if q[RELEASE_CARRY] > 0.5 and q[ON_RELEASE_VETO] > 0.5:
                ph = carried_phase(ph, g, q, mem[i], commit)
            phase[i] = ph
            v_z = 0.0  # the end-effector's vertical velocity, J_pos[2] . qdot (m/s; 0 for a state without dynamics)
            for j in range(o[13]):
                v_z += row[o[12] + 2 * o[13] + j] * row[o[8] + j]
            t_meet = -1.0  # the time left until the fingers are the object's width apart (s; -1: unknown)
            if o[6] >= 0 and (q[MEETS] > 0.5 or q[MEETS_ONSET] > 0.5):  # approach_veto.py: T_close (o - w) / (span - w)
                t_close, w, span = row[o[6] + N_SCENE], 2.0 * row[o[6] + 1], row[o[6] + 4]
                if t_close > 0.0 and w > 0.0 and span > w:
                    t_meet = t_close * min(max((row[FINGERS_AT] - w) / (span - w), 0.0), 1.0)
            geo[i, 6] = timed_close(a_raw[i], idx, q, ph, geo[i, 3], v_z, veto_i[0], t_meet, mem[i], commit)
            if on_scene and held_to_top(a_raw[i], idx, q, mem[i]):  # approach_veto.py: held until the pads' centres
                geo[i, 4] = veto_i[0] - row[o[6] + 6]  # are at the object's top (the veto height less pad_h)
            if temporal:
                temporal_row(a_raw[i], a_phys[i], idx, g, q, mem[i], commit)
            else:
                branch_a_row(a_raw[i], a_phys[i], ph, idx, g, q, mem[i], commit)
        return a_phys, phase, geo, status

    return phase_step


phase_step = _compile(SOURCE_KEY)
