"""The corrector: the four inference modes, Branch A + Branch B, and the capped blender (eq. 2).

    baseline  a = a_raw
    temporal  uniform EMA (alpha_temporal) on the position channels
    phys      a = (1 - c) a_raw + c a_A                 a_A = PhaseCorrect(a_raw)   (Branch A)
    phys_el   a = (1 - c) a_raw + c a_B                 a_B = w * a_A + (1 - w) * a_raw  (eq. 6)

Contract (do-no-harm):
- Wrong shapes (action dim, batch size, ndim) are programming errors: ValueError at once.
- At run time, an env whose correction cannot be computed -- invalid or non-finite state, a
  non-finite policy action, a mass matrix that is not positive definite, a non-finite result --
  gets the policy's action back unchanged, and the reason is counted in
  `Corrector.passthrough_counts` (a warning is issued the first time each reason occurs).
- Every corrected action lies within the layout's [low, high]; an env's own action is only ever
  returned unchanged or corrected, never made non-finite.
"""

from __future__ import annotations

import time
import warnings
from collections import Counter
from dataclasses import dataclass

import numpy as np
from numba import njit

from lerobot_physvla.core.branch_a import phase_step
from lerobot_physvla.core.config import PhysVLAConfig
from lerobot_physvla.core.corrections.base import N_MEM, channel_index, params
from lerobot_physvla.core.dynamics import ELGate, el_gate
from lerobot_physvla.core.phase import APPROACH
from lerobot_physvla.core.state import NONFINITE_OUTPUT, OK, REASONS, SINGULAR, PhysState, field_offsets



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
        t_branch_a_s: wall time of phase detection + Branch A (+ temporal EMA), s, whole batch.
        t_branch_b_s: wall time of the EL gate + blender, s, whole batch.
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


@njit(cache=True)
def _blend(a_raw, a_cand, phase, status, cap, grip, gripper_open, veto, low, high):
    """Eq. 2 with the gripper rule, clipping, and pass-through of every env whose status is not OK."""
    out = np.empty_like(a_raw)
    dev = np.zeros(a_raw.shape[0])
    for i in range(a_raw.shape[0]):
        if status[i] == OK:
            finite = True
            for k in range(a_raw.shape[1]):
                v = (1.0 - cap) * a_raw[i, k] + cap * a_cand[i, k]
                if veto and k == grip and phase[i] == APPROACH:
                    v = gripper_open
                v = min(max(v, low), high)
                finite = finite and np.isfinite(v)
                out[i, k] = v
                dev[i] = max(dev[i], abs(v - a_raw[i, k]))
            if finite:
                continue
            status[i] = NONFINITE_OUTPUT
            dev[i] = 0.0
        out[i] = a_raw[i]
    return out, dev


class Corrector:
    """Batched PhysVLA corrector over B envs with per-env memory.

    Attributes:
        cfg: the configuration (mode and every hyperparameter).
        batch_size: number of envs B.
        last: StepDiagnostics of the latest call.
        passthrough_counts: Counter of reasons (REASONS) an env's action was passed through unchanged.
        steps: number of env-steps seen (B per call; a chunk counts once).
    """

    def __init__(self, cfg: PhysVLAConfig | None = None, batch_size: int = 1):
        self.cfg = cfg if cfg is not None else PhysVLAConfig()
        self.cfg.validate()
        lay = self.layout = self.cfg.action_layout
        self.batch_size = b = int(batch_size)
        self.branch_b = ELGate(self.cfg) if self.cfg.mode == "phys_el" and self.cfg.el_mode != "off" else None
        self.passthrough_counts: Counter = Counter()
        self.steps = 0
        self.last: StepDiagnostics | None = None
        self._pos = lay.pos_index
        self._grip = -1 if lay.gripper is None else lay.gripper
        self._idx = channel_index(lay)
        self._p_a = params(self.cfg, lay)
        self._mem = np.zeros((b, N_MEM))  # per-env memory of the corrections (EMA), corrections/base.py
        self._offsets: dict[int, np.ndarray] = {}
        self._warned: set[str] = set()

    def reset(self, env_ids=None) -> None:
        """Forget per-env memory (EMAs) for env_ids (all envs if None), e.g. at an episode start."""
        sel = slice(None) if env_ids is None else np.asarray(env_ids)
        self._mem[sel] = 0.0

    # ------------------------------------------------------------------ API boundary
    def _check(self, actions, state: PhysState) -> np.ndarray:
        a = np.asarray(actions, dtype=np.float64)
        if a.ndim not in (2, 3):
            raise ValueError(f"physvla: actions must be (B, A) or (B, T, A), got shape {a.shape}")
        if a.shape[0] != self.batch_size or a.shape[-1] != self.layout.dim:
            raise ValueError(
                f"physvla: actions of shape {a.shape} do not match batch_size={self.batch_size} and the "
                f"action layout's dim={self.layout.dim}; set PhysVLAConfig.layout to the env's action layout"
            )
        if state.batch_size != self.batch_size:
            raise ValueError(f"physvla: state holds {state.batch_size} envs, corrector has {self.batch_size}")
        if self.branch_b is not None:
            self.branch_b.check_arm(state.n_joints)
        return a

    def __call__(self, actions, state: PhysState) -> np.ndarray:
        """Corrected actions, same shape as `actions` ((B, A) or (B, T, A)), float64."""
        t0 = time.perf_counter()
        a = self._check(actions, state)
        self.steps += self.batch_size
        flat = state.pack()
        n = state.n_joints
        if a.ndim == 2:
            out = self._step(a, flat, n, commit=True)
        else:
            out = a.copy()
            for t in range(a.shape[1] if self.cfg.chunk == "all" else 1):
                out[:, t] = self._step(np.ascontiguousarray(a[:, t]), flat, n, commit=(t == 0))
        self.last.t_total_s = time.perf_counter() - t0
        return out

    # ------------------------------------------------------------------ one step
    def _phase_offsets(self, n: int) -> np.ndarray:
        if n not in self._offsets:
            f = field_offsets(n)
            self._offsets[n] = np.array([f[k] for k in ("valid", "eef_pos", "obj_pos", "obj_rest_z", "target_pos")])
        return self._offsets[n]

    def _step(self, a_raw: np.ndarray, flat: np.ndarray, n: int, commit: bool) -> np.ndarray:
        """One control step for all envs. Only the committed step (a chunk's first) updates memory
        and the diagnostics."""
        cfg, lay = self.cfg, self.layout
        t0 = time.perf_counter()
        temporal = cfg.mode == "temporal"
        a_phys, phase, geo, status = phase_step(
            a_raw, flat, self._phase_offsets(n), self._idx, self._p_a, cfg.delta_grasp_m, cfg.h_lift_m,
            self._mem, commit, temporal,
        )
        t1 = time.perf_counter()
        weights, r_diag = np.zeros_like(a_raw), np.full((self.batch_size, 2), np.nan)
        if cfg.mode == "baseline":  # identity; phase and geometry above are kept for diagnostics
            status[:] = OK
            out, dev = a_raw.copy(), np.zeros(self.batch_size)
        else:
            if self.branch_b is not None:
                g = self.branch_b
                a_phys, weights, r_diag = el_gate(
                    a_raw, a_phys, flat, g.offsets(n), n, self._pos, g.params, g.flags, status, SINGULAR
                )
            cap = 1.0 if temporal else cfg.cap  # the temporal baseline is applied in full
            veto = cfg.gripper_rule == "veto" and not temporal
            out, dev = _blend(a_raw, a_phys, phase, status, cap, self._grip, lay.gripper_open, veto, lay.low, lay.high)
        t2 = time.perf_counter()
        if commit:
            if status.any():
                self._count(status)
                phase[status != OK] = -1
            self.last = StepDiagnostics(
                phase, geo[:, 0], geo[:, 1], geo[:, 2], r_diag[:, 0], r_diag[:, 1], weights, dev, status,
                t1 - t0, t2 - t1,
            )
        return out

    def _count(self, status: np.ndarray) -> None:
        for code in np.unique(status[status != OK]):
            why = REASONS[code]
            self.passthrough_counts[why] += int((status == code).sum())
            if why not in self._warned:
                self._warned.add(why)
                warnings.warn(
                    f"physvla: passing the policy's action through unchanged ({why}); see Corrector.passthrough_counts",
                    RuntimeWarning, stacklevel=4,
                )
