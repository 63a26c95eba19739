"""One control tick of the whole corrector, B envs, as one compiled call.

    phase + Branch A (branch_a.phase_step) -> Branch B (dynamics.el_gate) -> blender (eq. 2,
    blend.blend) -> adaptive low-pass (lowpass.adaptive_lowpass, when on) -> safety net (blend.guard)

The stages are the same numba functions the corrector can also run one by one (its `profile`
mode, which times Branch A and Branch B apart); fused, a tick costs one dispatch (~3 us of
argument checking) instead of four, and writes its diagnostics into one buffer the corrector owns instead of
returning them (boxing a returned array costs ~0.3 us).

Cache safety as in branch_a.py: `correct_tick` closes over a hash of every source file compiled
into it (`TICK_SOURCE_KEY`), so editing any stage compiles it afresh.

Integer parameters `ip` (int64):  [0:7] phase offsets (valid, eef_pos, obj_pos, obj_rest_z,
target_pos, pose_age, scene: -1 where the distances are fixed), [7:13] Branch B offsets (dt, qdot, M,
bias, tau, J_pos), [13] n joints, [14:17] position channels, [17:19] Branch B flags (el_mode,
weighting), [19] gripper channel (-1: none), [20] temporal, [21] baseline, [22] Branch B on, [23]
gripper veto, [24] low-pass on, [25:29] the phases where the low-pass acts (0/1 each).
Float parameters `fp`: [0] delta_grasp (m), [1] h_lift (m), [2] cap c, [3] gripper open value,
[4] low, [5] high (action units), [6:10] Branch B [metres_per_unit, damping, eps (N m), r0 (N m)],
[10:14] the authority per phase, [14:18] gripper veto [height, reach] (m, the pose error included),
then the configuration's [veto_height_m, veto_reach_m] (core/geometry.py), [18:26] low-pass
[alpha_max, lo, hi, metres_per_unit, 1 = target space, speed_hi, 1 = median, 1 = compensate], [26] how far
from open the last gripper command may lie and count as open (ActionLayout.gripper_hold_tol, action units).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numba import njit

from lerobot_physvla.core.blend import blend, guard
from lerobot_physvla.core.branch_a import DISPATCH_SOURCE, SOURCE_FILES, phase_step, source_key
from lerobot_physvla.core.dynamics import el_gate
from lerobot_physvla.core.lowpass import adaptive_lowpass
from lerobot_physvla.core.state import INVALID_DT, OK, SINGULAR, field_offsets

_CORE = Path(__file__).resolve().parent
TICK_SOURCE_FILES = (*SOURCE_FILES, Path(__file__).resolve(), _CORE / "blend.py", _CORE / "dynamics.py",
                     _CORE / "lowpass.py")
TICK_SOURCE_KEY = source_key(TICK_SOURCE_FILES, DISPATCH_SOURCE)

# layout of the integer parameters (module doc)
(IP_PHASE, IP_B, IP_N, IP_POS, IP_FLAGS, IP_GRIP, IP_TEMPORAL, IP_BASELINE, IP_BRANCH_B, IP_VETO, IP_LOWPASS,
 IP_LP_MASK, N_IP) = (0, 7, 13, 14, 17, 19, 20, 21, 22, 23, 24, 25, 29)
# layout of the float parameters
(FP_D_GRASP, FP_H_LIFT, FP_CAP, FP_GRIP_OPEN, FP_LOW, FP_HIGH, FP_B, FP_CAPS, FP_VETO, FP_LP, FP_GRIP_TOL, N_FP) = (
    0, 1, 2, 3, 4, 5, 6, 10, 14, 18, 26, 27)
# columns of the diagnostics buffer (B, N_DIAG + A): phase (-1 where passed through), status
# (REASONS code), guard (GUARDS code), d_obj_xy, d_tgt_xy, lift (m), |r_EL| (N m), r_energy (W),
# deviation max|a - a_raw| (action units), sum of Branch B weights, then the A weights
D_PHASE, D_STATUS, D_GUARD, D_OBJ, D_TGT, D_LIFT, D_R_EL, D_R_ENERGY, D_DEV, D_W_SUM, N_DIAG = range(11)
EPISODE_STEP = field_offsets(1)["episode_step"]  # a header field: the same offset for every joint count
# stream_tick's int64 arena iws: offsets into the float64 arena fws (fp, p_a, hold0, mem, lp_mem, last
# action, diag, ep_last), p_a's length, mem's and lp_mem's widths, offsets into the bool arena bws
# (absolute, has_last); then the tick's integer parameters ip (N_IP) and the channel index
(W_FP, W_PA, W_NPA, W_HOLD, W_MEM, W_NMEM, W_LP, W_NLP, W_LAST, W_DIAG, W_EP, W_ABS, W_HAS, N_W) = range(14)
# a recording row per env (diagnostics.EpisodeRecorder's arena, (capacity, B, width)), which stream_tick
# fills when given one: the raw action (A), the emitted action (A), the packed state's first REC_HEADER
# fields (valid, episode_step, dt, eef_pos), the diagnostics (N_DIAG + A), then the whole packed
# state (L) where the arena is that wide
REC_HEADER = 6


@njit(error_model="numpy")
def record_tick(diag, phase, status, g, geo, r, dev, w, commit):
    """Writes one tick's diagnostics into diag (columns D_*); returns the number of rows the
    safety net touched or (on commit) passed through."""
    events = 0
    for i in range(diag.shape[0]):
        diag[i, D_GUARD] = g[i]
        if g[i] != 0 or (commit and status[i] != OK):
            events += 1
        if commit:
            diag[i, D_PHASE] = phase[i] if status[i] == OK else -1
            diag[i, D_STATUS] = status[i]
            diag[i, D_OBJ], diag[i, D_TGT], diag[i, D_LIFT] = geo[i, 0], geo[i, 1], geo[i, 2]
            diag[i, D_R_EL], diag[i, D_R_ENERGY] = r[i, 0], r[i, 1]
            diag[i, D_DEV] = dev[i]
            w_sum = 0.0
            for k in range(w.shape[1]):
                diag[i, N_DIAG + k] = w[i, k]
                w_sum += w[i, k]
            diag[i, D_W_SUM] = w_sum
    return events


def _compile(key: int):
    @njit(cache=True, error_model="numpy")
    def correct_tick(a_raw, flat, ip, fp, idx, p_a, mem, lp_mem, absolute, hold0, last, has_last, commit, diag):
        """Corrected actions (B, A) for one tick (mem: Branch A's memory, lp_mem: the low-pass's).

        diag (B, N_DIAG + A), columns above: the guard column is written at every call, the
        others on commit only (a chunk's first step, or a single step).
        Returns (out (B, A), events): events = rows the safety net touched or (on commit) passed through.
        """
        key  # noqa: B018 - read, so it is in the closure and hence in numba's cache key
        b, a_dim = a_raw.shape
        temporal = ip[IP_TEMPORAL] != 0
        baseline = ip[IP_BASELINE] != 0
        a_phys, phase, geo, status = phase_step(
            a_raw, flat, ip[IP_PHASE:IP_N + 1], idx, p_a, fp[FP_D_GRASP], fp[FP_H_LIFT], fp[FP_VETO:FP_LP], mem, commit,
            temporal)
        w = np.zeros_like(a_raw)
        r = np.full((b, 2), np.nan)
        if baseline:  # identity inside the safety net; phase and geometry are kept for diagnostics
            status[:] = OK
            out = a_raw.copy()
            dev = np.zeros(b)
        else:
            if ip[IP_BRANCH_B] != 0:
                a_phys, w, r = el_gate(a_raw, a_phys, flat, ip[IP_B:IP_N], ip[IP_N], ip[IP_POS:IP_FLAGS], fp[FP_B:N_FP],
                                       ip[IP_FLAGS:IP_GRIP], status, SINGULAR, INVALID_DT)
            caps = np.ones(4) if temporal else fp[FP_CAPS:FP_VETO]  # the temporal baseline is applied in full
            out, dev = blend(a_raw, a_phys, phase, status, caps, ip[IP_GRIP], fp[FP_GRIP_OPEN], ip[IP_VETO], geo,
                             fp[FP_LOW], fp[FP_HIGH], last, has_last, fp[FP_GRIP_TOL])
            if ip[IP_LOWPASS] != 0:
                adaptive_lowpass(out, a_raw, phase, status, ip[IP_POS:IP_FLAGS], ip[IP_LP_MASK:N_IP], fp[FP_LP],
                                 fp[FP_LP + 1], fp[FP_LP + 2], lp_mem, commit, dev, flat, ip[IP_PHASE + 1], absolute,
                                 fp[FP_LP + 3], fp[FP_LP + 4] != 0.0, fp[FP_LP + 5], fp[FP_LP + 6] != 0.0,
                                 fp[FP_LP + 7] != 0.0)
        g = guard(out, a_raw, status, baseline, absolute, hold0, fp[FP_LOW], fp[FP_HIGH], last, has_last, commit)
        return out, record_tick(diag, phase, status, g, geo, r, dev, w, commit)

    return correct_tick


correct_tick = _compile(TICK_SOURCE_KEY)


def _compile_stream(key: int):
    # correct_tick is read as a module global here (a closure over a dispatcher would make numba
    # skip its cache and compile at every start); key keeps the cache keyed on every stage's source
    @njit(cache=True, error_model="numpy")
    def stream_tick(a_in, flat, fws, iws, bws, rows, k):
        """One control step of a stream of (B, A) actions, what a LeRobot step needs in one
        compiled call with few arguments (a call from Python costs ~8 us plus ~0.7 us per array
        argument when the caches are cold, as they are between physics steps):

        1. episode boundaries: an env whose packed `episode_step` went back, or that has none
           yet (NaN in ep_last), starts afresh (its Branch A and low-pass memory and last action
           forgotten, as Corrector.reset); ep_last keeps each env's counter;
        2. the tick (correct_tick, committed) on a_in cast to float64, its output in a_in's dtype;
        3. the recording: where rows (capacity, B, width) has a row k for these B envs, rows[k] gets
           this tick's raw and emitted actions, state header, diagnostics (and whole state where
           wide enough) (REC_HEADER above): the diagnostics a recorder keeps, written here rather
           than copied array by array in Python after the call. rows of shape (0, 0, 0): no recording.

        The corrector's arrays live in three arenas (Corrector.__init__), at offsets iws[W_*]:
        fws float64 (fp, p_a, hold0, mem, lp_mem, last, diag, ep_last), iws int64 (the offsets,
        the tick's integer parameters ip, the channel index), bws bool (absolute, has_last).
        Returns (out (B, A) in a_in's dtype, events as correct_tick).
        """
        key  # noqa: B018 - in the cache key, as above
        b, a_dim = a_in.shape
        n_d = N_DIAG + a_dim
        fp = fws[iws[W_FP] : iws[W_FP] + N_FP]
        p_a = fws[iws[W_PA] : iws[W_PA] + iws[W_NPA]]
        hold0 = fws[iws[W_HOLD] : iws[W_HOLD] + a_dim]
        mem = fws[iws[W_MEM] : iws[W_MEM] + b * iws[W_NMEM]].reshape((b, iws[W_NMEM]))
        lp_mem = fws[iws[W_LP] : iws[W_LP] + b * iws[W_NLP]].reshape((b, iws[W_NLP]))
        last = fws[iws[W_LAST] : iws[W_LAST] + b * a_dim].reshape((b, a_dim))
        diag = fws[iws[W_DIAG] : iws[W_DIAG] + b * n_d].reshape((b, n_d))
        ep_last = fws[iws[W_EP] : iws[W_EP] + b]
        ip = iws[N_W : N_W + N_IP]
        idx = iws[N_W + N_IP :]
        absolute = bws[iws[W_ABS] : iws[W_ABS] + a_dim]
        has_last = bws[iws[W_HAS] : iws[W_HAS] + b]
        for i in range(b):
            s = flat[i, EPISODE_STEP]
            if np.isnan(ep_last[i]) or s < ep_last[i]:
                mem[i, :] = 0.0
                lp_mem[i, :] = 0.0
                has_last[i] = False
            ep_last[i] = s
        a = np.empty((b, a_dim))
        for i in range(b):
            for j in range(a_dim):
                a[i, j] = a_in[i, j]
        out, events = correct_tick(a, flat, ip, fp, idx, p_a, mem, lp_mem, absolute, hold0, last, has_last, True,
                                   diag)
        res = np.empty_like(a_in)
        for i in range(b):
            for j in range(a_dim):
                res[i, j] = out[i, j]
        if 0 <= k < rows.shape[0] and rows.shape[1] == b and rows.shape[2] >= 2 * a_dim + REC_HEADER + n_d:
            o_h, o_d = 2 * a_dim, 2 * a_dim + REC_HEADER
            o_s = o_d + n_d
            whole = rows.shape[2] >= o_s + flat.shape[1]
            for i in range(b):
                for j in range(a_dim):
                    rows[k, i, j] = a_in[i, j]
                    rows[k, i, a_dim + j] = res[i, j]
                for j in range(REC_HEADER):
                    rows[k, i, o_h + j] = flat[i, j]
                for j in range(n_d):
                    rows[k, i, o_d + j] = diag[i, j]
                if whole:
                    for j in range(flat.shape[1]):
                        rows[k, i, o_s + j] = flat[i, j]
        return res, events

    return stream_tick


stream_tick = _compile_stream(TICK_SOURCE_KEY)
