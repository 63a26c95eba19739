"""The corrector: the four inference modes, Branch A + Branch B, and the capped blender (eq. 2).

    baseline  a = a_raw
    temporal  uniform EMA (alpha_temporal) on the position channels
    phys      a = (1 - c) a_raw + c a_A                 a_A = PhaseCorrect(a_raw)   (Branch A)
    phys_el   a = (1 - c) a_raw + c a_B                 a_B = w * a_A + (1 - w) * a_raw  (eq. 6)

Contract (do-no-harm), for every mode:
- Wrong shapes (action dim, batch size, ndim) are programming errors: ValueError at once.
- Nothing else raises at run time: zero, negative, huge or non-finite values in any state field
  or action are handled by status codes, never by exceptions (kernels use numpy's error model:
  a division by zero gives inf / nan, which the finite checks catch).
- An env whose correction cannot be computed -- invalid or non-finite state, dt <= 0, a
  non-finite policy action, a mass matrix that is not positive definite, a non-finite result --
  is passed through: it gets the policy's own action clipped to the layout's [low, high]; the
  reason is counted in `passthrough_counts` (warned the first time each occurs).
- Every emitted action is finite and inside [low, high]. A non-finite policy action is replaced
  by the layout's safe hold action (`ActionLayout.hold`: 0 on delta channels, the env's last
  emitted value on absolute ones, the gripper included), counted in `guard_counts` and warned once.
"""

from __future__ import annotations

import time
import warnings
from collections import Counter
from dataclasses import dataclass

import numpy as np

from lerobot_physvla.core.blend import blend, guard
from lerobot_physvla.core.branch_a import phase_step
from lerobot_physvla.core.config import PhysVLAConfig
from lerobot_physvla.core.corrections import channel_index, params
from lerobot_physvla.core.corrections.slots import N_MEM
from lerobot_physvla.core.direct_call import direct_entry
from lerobot_physvla.core.dynamics import ELGate, el_gate
from lerobot_physvla.core.lowpass import N_LP_MEM, adaptive_lowpass
from lerobot_physvla.core.state import (
    GUARD_CLIPPED, GUARD_HELD, GUARDS, INVALID_DT, OK, REASONS, SINGULAR, PhysState, field_offsets, n_joints_from_size,
    upgrade,
)
from lerobot_physvla.core.tick import (
    D_DEV, D_GUARD, D_LIFT, D_OBJ, D_PHASE, D_R_EL, D_R_ENERGY, D_STATUS, D_TGT, FP_B, FP_CAP, FP_CAPS, FP_D_GRASP,
    FP_GRIP_OPEN, FP_GRIP_TOL, FP_H_LIFT, FP_HIGH, FP_LOW, FP_LP, FP_VETO, IP_B, IP_BASELINE, IP_BRANCH_B, IP_FLAGS,
    IP_GRIP,
    EPISODE_STEP, IP_LOWPASS, IP_LP_MASK, IP_N, IP_PHASE, IP_POS, IP_TEMPORAL, IP_VETO, N_DIAG, N_FP, N_IP, N_W,
    REC_HEADER, W_DIAG, W_EP, W_FP, W_HAS, W_HOLD, W_LAST, W_LP, W_MEM, W_NLP, W_NMEM, W_NPA, W_PA, W_ABS,
    correct_tick, record_tick, stream_tick,
)



_NAN = float("nan")
_STREAM_DTYPES = (np.dtype(np.float32), np.dtype(np.float64))  # action dtypes stream_tick is compiled for
_NO_ROWS = np.zeros((0, 0, 0))  # stream_tick's recording arena when nothing records


def _rows_ok(rows) -> bool:
    """A recording arena stream_tick may write into: a C-contiguous, writeable float64 (capacity, B, width)."""
    return (type(rows) is np.ndarray and rows.dtype == np.float64 and rows.ndim == 3 and rows.flags.carray
            and rows.flags.writeable)


def record_row(rows: np.ndarray, k: int, raw: np.ndarray, out: np.ndarray, flat: np.ndarray, diag: np.ndarray) -> None:
    """rows[k] as stream_tick writes it (core/tick.py REC_HEADER), from Python: for the calls that do
    not take the one-call path (chunks, other dtypes). A chunk's step 0 is the row."""
    if not (0 <= k < rows.shape[0] and rows.shape[1] == raw.shape[0]):
        return
    a_dim, n_d = raw.shape[-1], diag.shape[1]
    o_d = 2 * a_dim + REC_HEADER
    if rows.shape[2] < o_d + n_d:
        return
    row = rows[k]
    row[:, :a_dim] = raw[:, 0] if raw.ndim == 3 else raw
    row[:, a_dim : 2 * a_dim] = out[:, 0] if out.ndim == 3 else out
    row[:, 2 * a_dim : o_d] = flat[:, :REC_HEADER]
    row[:, o_d : o_d + n_d] = diag
    if rows.shape[2] >= o_d + n_d + flat.shape[1]:
        row[:, o_d + n_d : o_d + n_d + flat.shape[1]] = flat


@dataclass
class StepDiagnostics:
    """What the corrector saw and did at one call, per env (for a chunk: its first step).

    Attributes:
        phase: (B,) int8 `Phase` values (-1 where passed through or in baseline mode).
        d_obj_xy, d_tgt_xy, lift: (B,) metres.
        r_el: (B,) |r_EL|, N m (NaN where Branch B did not run).
        r_energy: (B,) work-energy residual, W (NaN where Branch B did not run).
        weights: (B, A) Branch B weights (0 where it did not run).
        deviation: (B,) max |a - a_raw| over channels, action units.
        status: (B,) index into REASONS (0 = corrected).
        t_branch_a_s: wall time of phase detection + Branch A (+ temporal EMA), s, whole batch
            (NaN unless the corrector profiles: fused, the stages are one compiled call).
        t_branch_b_s: wall time of the EL gate + blender + safety net, s, whole batch (idem).
        t_total_s: wall time of the whole call, s, whole batch.
    """

    phase: np.ndarray
    d_obj_xy: np.ndarray
    d_tgt_xy: np.ndarray
    lift: np.ndarray
    r_el: np.ndarray
    r_energy: np.ndarray
    weights: np.ndarray
    deviation: np.ndarray
    status: np.ndarray
    t_branch_a_s: float = 0.0
    t_branch_b_s: float = 0.0
    t_total_s: float = 0.0

    @property
    def passthrough(self) -> np.ndarray:
        return self.status != OK


class Corrector:
    """Batched PhysVLA corrector over B envs with per-env memory.

    Attributes:
        cfg: the configuration (mode and every hyperparameter).
        batch_size: number of envs B.
        last: StepDiagnostics of the latest call (built only when read).
        diag_buffer: (B, N_DIAG + A) diagnostics of the latest committed step, overwritten in
            place by every call (columns D_* in tick.py; `last` is a copy in named fields).
        profile: run the tick's stages one by one and time Branch A and B apart (slower; for
            benchmarks). By default a tick is one compiled call (tick.py).
        passthrough_counts: Counter of reasons (REASONS) an env's action was passed through (clipped).
        guard_counts: Counter of what the safety net did (GUARDS): clipped_to_bounds,
            held_nonfinite_action.
        steps: number of env-steps seen (B per call; a chunk counts once).
    """

    def __init__(self, cfg: PhysVLAConfig | None = None, batch_size: int = 1, warmup: bool = True,
                 profile: bool = False):
        self.cfg = cfg if cfg is not None else PhysVLAConfig()
        self.cfg.validate()
        lay = self.layout = self.cfg.action_layout
        self.batch_size = b = int(batch_size)
        self.profile = bool(profile)
        self.branch_b = ELGate(self.cfg) if self.cfg.mode == "phys_el" and self.cfg.el_mode != "off" else None
        self._b_on = True  # set_branch_b
        self.passthrough_counts: Counter = Counter()
        self.guard_counts: Counter = Counter()
        self.steps = 0
        self._pos = lay.pos_index
        self._grip = -1 if lay.gripper is None else lay.gripper
        self._flat_width, self._n = -1, 0  # packed-state width last seen and its joint count
        self._params: dict[int, np.ndarray] = {}  # joint count -> integer parameters of the tick (tick.py)
        self._arenas(b, channel_index(lay), params(self.cfg, lay), lay.hold(), lay.absolute_mask)
        self._fp[:] = self._float_params()
        self.diag_buffer[:, D_PHASE] = -1
        self.diag_buffer[:, D_R_EL : D_R_ENERGY + 1] = np.nan
        self._ep_last[:] = np.nan  # each env's episode_step at its last streamed call (NaN: none yet)
        self._warned: set[str] = set()
        self._diag: StepDiagnostics | None = None  # built from the buffers when `last` is read
        self._has_diag = False
        self._t_a = self._t_b = self._t_total = 0.0
        if warmup and self._warm_key() not in Corrector._warm:
            self.warm_up()

    def _arenas(self, b: int, idx: np.ndarray, p_a: np.ndarray, hold0: np.ndarray, absolute: np.ndarray) -> None:
        """The corrector's arrays as views into three arenas, so that stream_tick takes three
        arguments for all of them (tick.py, W_*): float64 fws (fp, p_a, hold0, Branch A memory,
        low-pass memory, last action, diagnostics, ep_last), int64 iws (offsets, the tick's
        integer parameters, the channel index), bool bws (absolute channels, has_last)."""
        a_dim = len(hold0)
        sizes = (("_fp", N_FP, None), ("_p_a", len(p_a), None), ("_hold0", a_dim, None), ("_mem", b * N_MEM, N_MEM),
                 ("_lp_mem", b * N_LP_MEM, N_LP_MEM), ("_last_out", b * a_dim, a_dim),
                 ("diag_buffer", b * (N_DIAG + a_dim), N_DIAG + a_dim), ("_ep_last", b, None))
        self._fws = np.zeros(sum(n for _, n, _ in sizes))
        self._iws = np.zeros(N_W + N_IP + len(idx), np.int64)
        self._bws = np.zeros(a_dim + b, np.bool_)
        offsets, o = {}, 0
        for name, n, width in sizes:
            view = self._fws[o : o + n]
            setattr(self, name, view if width is None else view.reshape(b, width))
            offsets[name], o = o, o + n
        w = self._iws
        w[W_FP], w[W_PA], w[W_NPA], w[W_HOLD] = offsets["_fp"], offsets["_p_a"], len(p_a), offsets["_hold0"]
        w[W_MEM], w[W_NMEM], w[W_LP], w[W_NLP] = offsets["_mem"], N_MEM, offsets["_lp_mem"], N_LP_MEM
        w[W_LAST], w[W_DIAG], w[W_EP], w[W_ABS], w[W_HAS] = (offsets["_last_out"], offsets["diag_buffer"],
                                                             offsets["_ep_last"], 0, a_dim)
        self._p_a[:], self._hold0[:] = p_a, hold0
        self._iws_ip = w[N_W : N_W + N_IP]  # the integer parameters of the joint count in _iws_n
        self._iws_n = -1
        self._rows_checked = None  # the recording arena last checked by correct_stream
        self._idx = w[N_W + N_IP :]
        self._idx[:] = idx
        self._absolute, self._has_last = self._bws[:a_dim], self._bws[a_dim:]
        self._absolute[:] = absolute

    _warm: set = set()  # configurations whose kernels this process has already run
    # action dtype -> stream_tick's compiled overload for (that dtype's C (B, A) actions, C float64
    # (B, L) states, the three arenas), called directly (core/direct_call.py); correct_stream checks
    # dtype, dimensions and C order before it calls one
    _stream_calls: dict = {}

    def _warm_key(self):
        c = self.cfg
        return c.mode, c.el_mode, c.weighting, c.gripper_rule, c.chunk, c.lowpass, self.profile

    def warm_up(self) -> None:
        """Run every kernel of this mode once on a synthetic state and forget it, so that no
        compilation or cache load happens inside a control tick. Types do not depend on the
        joint count, so one run covers every arm."""
        n = self.layout.dim if self.cfg.weighting == "joint_diag" else 7
        st = PhysState.empty(self.batch_size, n)
        st.valid[:], st.dt[:], st.M[:] = 1.0, 0.05, np.eye(n)
        st.J_pos[:, :, :3] = np.eye(3)
        a = np.zeros((self.batch_size, self.layout.dim))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            self(a, st)
            self(a[:, None], st)
            self.passthrough(a, "warm_up")
            flat = st.pack()
            for dtype in _STREAM_DTYPES:
                self.correct_stream(a.astype(dtype), flat)
        self.passthrough_counts.clear()
        self.guard_counts.clear()
        self._warned.clear()
        self.steps = 0
        self._diag, self._has_diag = None, False
        self.reset()
        Corrector._warm.add(self._warm_key())

    def reset(self, env_ids=None) -> None:
        """Forget per-env memory (EMAs, last action) for env_ids (all if None), e.g. at an episode start."""
        sel = slice(None) if env_ids is None else np.asarray(env_ids)
        self._mem[sel] = 0.0
        self._lp_mem[sel] = 0.0
        self._has_last[sel] = False
        self._ep_last[sel] = np.nan

    # ------------------------------------------------------------------ API boundary
    def _check(self, actions) -> np.ndarray:
        a = np.ascontiguousarray(actions, dtype=np.float64)
        if a.ndim not in (2, 3):
            raise ValueError(f"physvla: actions must be (B, A) or (B, T, A), got shape {a.shape}")
        if a.shape[0] != self.batch_size or a.shape[-1] != self.layout.dim:
            raise ValueError(
                f"physvla: actions of shape {a.shape} do not match batch_size={self.batch_size} and the "
                f"action layout's dim={self.layout.dim}; set PhysVLAConfig.layout to the env's action layout"
            )
        return a

    def __call__(self, actions, state: PhysState) -> np.ndarray:
        """Corrected actions, same shape as `actions` ((B, A) or (B, T, A)), float64."""
        t0 = time.perf_counter()
        a = self._check(actions)
        if state.batch_size != self.batch_size:
            raise ValueError(f"physvla: state holds {state.batch_size} envs, corrector has {self.batch_size}")
        return self._run(a, state.pack(), t0)

    def correct_packed(self, actions, flat: np.ndarray) -> np.ndarray:
        """As `__call__`, with the states already packed: flat (B, packed_size(n)) float64."""
        t0 = time.perf_counter()
        return self._run(self._check(actions), flat, t0)

    def correct_stream(self, actions, flat, rows=None, k: int = 0) -> np.ndarray:
        """One step of a stream of control steps: as correct_packed for (B, A) actions, and an env
        whose packed `episode_step` went back (a reset), or that has not been seen since the
        corrector was built or reset, starts afresh first (`reset` of that env).

        rows, k: a recording arena (capacity, B, width) float64 C-contiguous and the row to fill
        with this step's raw and emitted actions, state header, diagnostics (and whole state where
        wide enough): core/tick.py REC_HEADER, diagnostics.EpisodeRecorder.slot. None: no recording.

        Where it can -- actions a C-contiguous, aligned, writeable float32 / float64 (B, A) numpy
        array, flat the (B, L) float64 packed states (the same), not profiling -- this is one compiled call
        (tick.stream_tick) and the output comes back in the actions' dtype; elsewhere the same through the
        one path every entry takes (`_run`: resets, the tick, the recording), float64.
        """
        t0 = time.perf_counter()
        if rows is None:
            rows = _NO_ROWS
        elif rows is not self._rows_checked:  # checked once per arena: the direct call trusts its types
            if not _rows_ok(rows):
                raise ValueError("physvla: a recording arena must be a C-contiguous writeable float64 "
                                 "(capacity, B, width) array")
            self._rows_checked = rows
        if type(flat) is np.ndarray and flat.ndim == 2 and flat.shape[1] != self._flat_width:
            flat = upgrade(flat)  # a packed state from before pose_age: age 0
            if flat.shape[1] != self._flat_width:
                self._set_width(flat.shape[1])
        if (type(actions) is np.ndarray and actions.ndim == 2 and actions.dtype in _STREAM_DTYPES
                and actions.flags.carray and type(flat) is np.ndarray and flat.ndim == 2
                and flat.shape[1] == self._flat_width and flat.dtype == np.float64 and flat.flags.carray
                and actions.shape[0] == self.batch_size == flat.shape[0] and actions.shape[1] == self.layout.dim
                and not self.profile):
            if self._iws_n != self._n:  # the integer parameters of this joint count into the arena
                self._iws_ip[:] = self._int_params(self._n)
                self._iws_n = self._n
            call = Corrector._stream_calls.get(actions.dtype)
            if call is None:  # the compiled overload for this action dtype, called without numba's dispatch
                call = Corrector._stream_calls[actions.dtype] = direct_entry(
                    stream_tick, actions, flat, self._fws, self._iws, self._bws, _NO_ROWS, 0)
            out, events = call(actions, flat, self._fws, self._iws, self._bws, rows, k)
            self.steps += self.batch_size
            self._t_a = self._t_b = _NAN
            self._diag, self._has_diag = None, True
            if events:
                self._count_events(True)
            self._t_total = time.perf_counter() - t0
            return out
        return self._run(self._check(actions), flat, t0, stream=True, rows=rows, k=k)

    def _set_width(self, width: int) -> None:
        """A new packed-state width: its joint count, checked once (ValueError for a width no arm
        has, or an arm Branch B's layout does not fit)."""
        n = n_joints_from_size(width)
        if self.branch_b is not None:
            self.branch_b.check_arm(n)
        self._flat_width, self._n = width, n

    def _run(self, a: np.ndarray, flat, t0: float, stream: bool = False, through: bool = False,
             rows: np.ndarray = _NO_ROWS, k: int = 0) -> np.ndarray:
        """The one way actions go through the corrector, whichever entry they came by: a (B, A) step or a
        (B, T, A) chunk, its steps one `_tick` each (only the first commits memory and diagnostics; with
        chunk="first" the later ones go through the safety net alone). stream: an env whose packed
        episode_step went back, or that is new, starts afresh first; rows, k: the recording row to fill.
        through: every step goes through the safety net alone (`passthrough`)."""
        if not through:  # the packed states (B, L) as the kernels take them: C float64, the width checked once
            if type(flat) is not np.ndarray:
                flat = np.asarray(flat)
            if flat.ndim != 2 or flat.shape[0] != self.batch_size:
                raise ValueError(f"physvla: packed state of shape {flat.shape}, corrector has {self.batch_size} envs")
            if flat.shape[1] != self._flat_width:
                flat = upgrade(flat)  # a packed state from before pose_age: age 0
                if flat.shape[1] != self._flat_width:
                    self._set_width(flat.shape[1])
            if flat.dtype != np.float64 or not flat.flags.c_contiguous:
                flat = np.ascontiguousarray(flat, dtype=np.float64)
            if stream and flat.shape[1] > EPISODE_STEP:
                step = flat[:, EPISODE_STEP]
                fresh = np.isnan(self._ep_last) | (step < self._ep_last)
                if fresh.any():
                    self.reset(np.flatnonzero(fresh))
                self._ep_last[:] = step
            self.steps += self.batch_size
        if a.ndim == 2:
            out = self._tick(a, flat, True, through)
        else:
            out = np.empty_like(a)
            n_corrected = a.shape[1] if self.cfg.chunk == "all" else 1
            for t in range(a.shape[1]):
                out[:, t] = self._tick(np.ascontiguousarray(a[:, t]), flat, t == 0, through or t >= n_corrected)
        if rows is not _NO_ROWS and rows.shape[0]:
            record_row(rows, k, a, out, flat, self.diag_buffer)
        if not through:
            self._t_total = time.perf_counter() - t0
        return out

    def passthrough(self, actions, reason: str) -> np.ndarray:
        """The actions passed through (clipped, non-finite ones held) for a reason the caller knows
        (e.g. no state reached it); counted in passthrough_counts under `reason`, not warned."""
        out = self._run(self._check(actions), None, 0.0, through=True)
        self.passthrough_counts[reason] += self.batch_size  # the caller, who knows why, warns
        return out

    @property
    def last(self) -> StepDiagnostics | None:
        """StepDiagnostics of the latest call (None before the first); copies, built when read."""
        if not self._has_diag:
            return None
        if self._diag is None:
            d = self.diag_buffer
            self._diag = StepDiagnostics(
                d[:, D_PHASE].astype(np.int8), d[:, D_OBJ].copy(), d[:, D_TGT].copy(), d[:, D_LIFT].copy(),
                d[:, D_R_EL].copy(), d[:, D_R_ENERGY].copy(), d[:, N_DIAG:].copy(), d[:, D_DEV].copy(),
                d[:, D_STATUS].astype(np.int8), self._t_a, self._t_b)
        self._diag.t_total_s = self._t_total
        return self._diag

    # ------------------------------------------------------------------ one step
    def _float_params(self) -> np.ndarray:
        cfg, lay = self.cfg, self.layout
        fp = np.zeros(N_FP)
        e = cfg.pose_error_told_m  # the pose error the distances answer to (docs/method.md, "Pose error"), m
        fp[FP_D_GRASP], fp[FP_H_LIFT], fp[FP_CAP] = cfg.delta_grasp_m, cfg.lifted_m, cfg.cap  # eq. 3
        fp[FP_GRIP_OPEN], fp[FP_LOW], fp[FP_HIGH] = lay.gripper_open, lay.low, lay.high
        if self.branch_b is not None:
            fp[FP_B:FP_CAPS] = self.branch_b.params
        fp[FP_CAPS:FP_VETO] = cfg.caps
        # the gripper veto holds back a close only where it is sure no grasp can close: its distances + e (a
        # reach of 0, the whole approach phase, is delta_grasp)
        fp[FP_VETO:FP_LP] = ((cfg.veto_height_m + e if cfg.veto_height_m > 0 else 0.0),
                             (cfg.veto_reach_m or (cfg.delta_grasp_m if e > 0 else 0.0)) + e,
                             cfg.veto_height_m, cfg.veto_reach_m)  # as configured: core/geometry.py derives from them
        fp[FP_GRIP_TOL] = lay.gripper_hold_tol
        fp[FP_LP:FP_GRIP_TOL] = (cfg.lowpass_alpha_max, cfg.lowpass_rough_lo, cfg.lowpass_rough_hi,
                                 lay.metres_per_unit, cfg.lowpass_space == "target", cfg.lowpass_speed_hi,
                                 cfg.lowpass_rough == "median", cfg.lowpass_lag == "compensate")
        return fp

    def _int_params(self, n: int) -> np.ndarray:
        """The tick's integer parameters for an arm of n joints (layout in tick.py), cached."""
        ip = self._params.get(n)
        if ip is None:
            cfg, f = self.cfg, field_offsets(n)
            ip = np.zeros(N_IP, np.int64)
            ip[IP_PHASE:IP_B] = [f[k] for k in ("valid", "eef_pos", "obj_pos", "obj_rest_z", "target_pos", "pose_age",
                                                 "scene")]
            if cfg.geometry != "scene":
                ip[IP_B - 1] = -1  # no scene offset: the distances as configured
            ip[IP_B:IP_N] = [f[k] for k in ("dt", "qdot", "M", "bias", "tau", "J_pos")]
            ip[IP_N], ip[IP_POS:IP_FLAGS] = n, self._pos
            if self.branch_b is not None:
                ip[IP_FLAGS:IP_GRIP] = self.branch_b.flags
            temporal = cfg.mode == "temporal"
            ip[IP_GRIP], ip[IP_TEMPORAL], ip[IP_BASELINE] = self._grip, temporal, cfg.mode == "baseline"
            ip[IP_BRANCH_B] = self.branch_b is not None and self._b_on
            ip[IP_VETO] = 0 if cfg.gripper_rule != "veto" or temporal else 1 if cfg.veto_reopen else 2
            ip[IP_LOWPASS] = cfg.lowpass == "adaptive" and cfg.mode in ("phys", "phys_el")
            ip[IP_LP_MASK:N_IP] = cfg.lowpass_mask
            self._params[n] = ip
        return ip

    def set_branch_b(self, on: bool) -> None:
        """Run Branch B (the EL gate) from the next call on, or not: for a caller that finds its
        residual meaningless on a tick (e.g. dominated by sensor noise, core/noise_guard.py).
        Nothing changes for a mode without Branch B."""
        if self.branch_b is None or bool(on) == self._b_on:
            return
        self._b_on = bool(on)
        for ip in self._params.values():
            ip[IP_BRANCH_B] = self._b_on
        self._iws_n = -1  # the arena's copy is refreshed at the next streamed call

    def _count_guards(self, g: np.ndarray) -> None:
        for code in (GUARD_CLIPPED, GUARD_HELD):
            k = int((g == code).sum())
            if k:
                self.guard_counts[GUARDS[code]] += k
        if (g == GUARD_HELD).any():
            self._warn_once("held", "physvla: the policy emitted a non-finite action; the env executes the "
                            "layout's hold action instead (0 deltas, last gripper command); see guard_counts")

    def _tick(self, a_raw: np.ndarray, flat, commit: bool, through: bool) -> np.ndarray:
        """One control step for all envs: the fused compiled tick (tick.correct_tick), or its stages one
        by one, timed apart, when profiling, or the safety net alone when `through`. Only the committed
        step (a chunk's first) updates memory and the diagnostics."""
        if through:
            out = a_raw.copy()
            lay = self.layout
            g = guard(out, a_raw, np.zeros(self.batch_size, np.int8), True, self._absolute, self._hold0, lay.low,
                      lay.high, self._last_out, self._has_last, commit)
            if g.any():
                self._count_guards(g)
            return out
        ip = self._int_params(self._n)
        if self.profile:
            out, events = self._staged(a_raw, flat, ip, commit)
        else:
            out, events = correct_tick(a_raw, flat, ip, self._fp, self._idx, self._p_a, self._mem, self._lp_mem,
                                       self._absolute, self._hold0, self._last_out, self._has_last, commit,
                                       self.diag_buffer)
            self._t_a = self._t_b = _NAN  # not timed apart (see `profile`)
        if commit:
            self._diag, self._has_diag = None, True
        if events:
            self._count_events(commit)
        return out

    def _count_events(self, commit: bool) -> None:
        """The safety net acted or an env was passed through: count and warn."""
        d = self.diag_buffer
        g = d[:, D_GUARD].astype(np.int8)
        if g.any():
            self._count_guards(g)
        if commit and d[:, D_STATUS].any():
            self._count(d[:, D_STATUS].astype(np.int8))

    def _staged(self, a_raw: np.ndarray, flat: np.ndarray, ip: np.ndarray, commit: bool) -> tuple[np.ndarray, int]:
        """The tick's stages called one by one (the same kernels as tick.correct_tick), Branch A
        and Branch B + blend timed apart into the diagnostics."""
        cfg, fp = self.cfg, self._fp
        t0 = time.perf_counter()
        temporal, baseline = bool(ip[IP_TEMPORAL]), bool(ip[IP_BASELINE])
        a_phys, phase, geo, status = phase_step(a_raw, flat, ip[IP_PHASE:IP_N + 1], self._idx, self._p_a,
                                                fp[FP_D_GRASP], fp[FP_H_LIFT], fp[FP_VETO:FP_LP], self._mem, commit,
                                                temporal)
        t1 = time.perf_counter()
        w, r = np.zeros_like(a_raw), np.full((self.batch_size, 2), np.nan)
        if baseline:
            status[:] = OK
            out, dev = a_raw.copy(), np.zeros(self.batch_size)
        else:
            if self.branch_b is not None:
                a_phys, w, r = el_gate(a_raw, a_phys, flat, ip[IP_B:IP_N], ip[IP_N], ip[IP_POS:IP_FLAGS],
                                       fp[FP_B:FP_CAPS], ip[IP_FLAGS:IP_GRIP], status, SINGULAR, INVALID_DT)
            caps = np.ones(4) if temporal else fp[FP_CAPS:FP_VETO]
            out, dev = blend(a_raw, a_phys, phase, status, caps, self._grip, fp[FP_GRIP_OPEN], int(ip[IP_VETO]), geo,
                             fp[FP_LOW], fp[FP_HIGH], self._last_out, self._has_last, fp[FP_GRIP_TOL])
            if ip[IP_LOWPASS]:
                adaptive_lowpass(out, a_raw, phase, status, ip[IP_POS:IP_FLAGS], ip[IP_LP_MASK:N_IP], fp[FP_LP],
                                 fp[FP_LP + 1], fp[FP_LP + 2], self._lp_mem, commit, dev, flat, ip[IP_PHASE + 1],
                                 self._absolute, fp[FP_LP + 3], fp[FP_LP + 4] != 0.0, fp[FP_LP + 5],
                                 fp[FP_LP + 6] != 0.0, fp[FP_LP + 7] != 0.0)
        lay = self.layout
        g = guard(out, a_raw, status, baseline, self._absolute, self._hold0, lay.low, lay.high, self._last_out,
                  self._has_last, commit)
        t2 = time.perf_counter()
        if commit:
            self._t_a, self._t_b = t1 - t0, t2 - t1
        return out, record_tick(self.diag_buffer, phase, status, g, geo, r, dev, w, commit)

    def _warn_once(self, key: str, message: str) -> None:
        if key not in self._warned:
            self._warned.add(key)
            warnings.warn(message, RuntimeWarning, stacklevel=5)

    def _count(self, status: np.ndarray) -> None:
        for code in np.unique(status[status != OK]):
            why = REASONS[code]
            self.passthrough_counts[why] += int((status == code).sum())
            self._warn_once(why, f"physvla: passing the policy's action through ({why}, clipped to the action "
                            "bounds); see Corrector.passthrough_counts")
