"""The corrector: the four inference modes, Branch A + Branch B, and the capped blender (eq. 2).

    baseline  a = a_raw
    temporal  uniform EMA (alpha_temporal) on the position channels
    phys      a = (1 - c) a_raw + c a_A                 a_A = PhaseCorrect(a_raw)   (Branch A)
    phys_el   a = (1 - c) a_raw + c a_B                 a_B = w * a_A + (1 - w) * a_raw  (eq. 6)

Contract (do-no-harm):
- Wrong shapes (action dim, batch size, ndim) are programming errors: ValueError at once.
- At run time, an env whose correction cannot be computed -- invalid or non-finite state, a
  non-finite policy action, a numerical failure -- gets the policy's action back unchanged, and
  the reason is counted in `Corrector.passthrough_counts`.
- Every corrected action lies within the layout's [low, high]; an env's own action is only ever
  returned unchanged or corrected, never made non-finite.
"""

from __future__ import annotations

import time
import warnings
from collections import Counter
from dataclasses import dataclass

import numpy as np

from .config import PhysVLAConfig
from .dynamics import ELGate
from .phase import Phase, PhaseCorrector, detect_phase, xy_distance
from .state import PhysState


@dataclass
class StepDiagnostics:
    """What the corrector saw and did at one call, per env (for a chunk: its first step).

    Attributes:
        phase: (B,) int8 `Phase` values (-1 where passed through).
        d_obj_xy, d_tgt_xy, lift: (B,) metres.
        r_el: (B,) |r_EL|, N m (NaN where Branch B did not run).
        r_energy: (B,) work-energy residual, W (NaN where Branch B did not run).
        weights: (B, A) Branch B weights (0 where it did not run).
        deviation: (B,) max |a - a_raw| over channels, action units.
        passthrough: (B,) True where the raw action was returned unchanged for a reason.
        t_branch_a_s, t_branch_b_s, t_total_s: wall time of this call, seconds (whole batch).
    """

    phase: np.ndarray
    d_obj_xy: np.ndarray
    d_tgt_xy: np.ndarray
    lift: np.ndarray
    r_el: np.ndarray
    r_energy: np.ndarray
    weights: np.ndarray
    deviation: np.ndarray
    passthrough: np.ndarray
    t_branch_a_s: float = 0.0
    t_branch_b_s: float = 0.0
    t_total_s: float = 0.0


class Corrector:
    """Batched PhysVLA corrector over B envs with per-env memory.

    Attributes:
        cfg: the configuration (mode and every hyperparameter).
        batch_size: number of envs B.
        last: StepDiagnostics of the latest call.
        passthrough_counts: Counter of reasons an env's action was passed through unchanged.
        steps: number of env-steps seen (B per call).
    """

    def __init__(self, cfg: PhysVLAConfig | None = None, batch_size: int = 1):
        self.cfg = cfg if cfg is not None else PhysVLAConfig()
        self.cfg.validate()
        self.layout = self.cfg.action_layout
        self.batch_size = int(batch_size)
        self.branch_a = PhaseCorrector(self.cfg, self.batch_size)
        self.branch_b = ELGate(self.cfg) if self.cfg.mode == "phys_el" and self.cfg.el_mode != "off" else None
        self.passthrough_counts: Counter = Counter()
        self.steps = 0
        self.last: StepDiagnostics | None = None
        self._temporal = np.zeros((self.batch_size, 3))
        self._temporal_init = np.zeros(self.batch_size, dtype=bool)
        self._warned: set[str] = set()

    def reset(self, env_ids=None) -> None:
        """Forget per-env memory (EMAs) for env_ids (all envs if None), e.g. at an episode start."""
        sel = slice(None) if env_ids is None else np.asarray(env_ids)
        self.branch_a.reset(None if env_ids is None else sel)
        self._temporal[sel] = 0.0
        self._temporal_init[sel] = False

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
        return a

    def __call__(self, actions, state: PhysState) -> np.ndarray:
        """Corrected actions, same shape as `actions` ((B, A) or (B, T, A)), float64."""
        t0 = time.perf_counter()
        a = self._check(actions, state)
        self.steps += self.batch_size
        if self.cfg.mode == "baseline":
            self.last = self._diag_passthrough(a[:, 0] if a.ndim == 3 else a, np.zeros(self.batch_size, bool))
            self.last.t_total_s = time.perf_counter() - t0
            return a.copy()
        if a.ndim == 2:
            out = self._step(a, state, commit=True)
        else:
            out = a.copy()
            steps = range(a.shape[1]) if self.cfg.chunk == "all" else range(1)
            for t in steps:
                out[:, t] = self._step(a[:, t], state, commit=(t == 0), record=(t == 0))
        self.last.t_total_s = time.perf_counter() - t0
        return out

    # ------------------------------------------------------------------ one step
    def _step(self, a_raw: np.ndarray, state: PhysState, commit: bool, record: bool = True) -> np.ndarray:
        ok = state.valid & state.is_finite()
        reasons = {}
        if not ok.all():
            reasons["invalid_state"] = ~state.valid
            reasons["nonfinite_state"] = state.valid & ~ok
        finite_a = np.isfinite(a_raw).all(axis=1)
        if not finite_a.all():
            reasons["nonfinite_action"] = ~finite_a
            ok &= finite_a
        commit_mask = ok & commit

        try:
            if not ok.all():  # keep bad rows from poisoning the batched linear algebra
                state = _with_placeholder_rows(state, ~ok)
            out, diag = self._correct(np.where(ok[:, None], a_raw, 0.0), state, commit_mask)
        except (np.linalg.LinAlgError, FloatingPointError, ValueError) as e:
            if isinstance(e, ValueError) and "physvla" in str(e):
                raise
            reasons = {f"error:{type(e).__name__}": np.ones(self.batch_size, bool)}
            ok = np.zeros(self.batch_size, bool)
            self._warn_once(type(e).__name__, f"physvla: correction failed ({e}); passing actions through")
            out, diag = a_raw.copy(), self._diag_passthrough(a_raw, np.ones(self.batch_size, bool))

        bad_out = ok & ~np.isfinite(out).all(axis=1)
        if bad_out.any():
            reasons["nonfinite_output"] = bad_out
            ok &= ~bad_out
        out = np.where(ok[:, None], out, a_raw)
        if record:
            for why, mask in reasons.items():
                n = int(mask.sum())
                if n:
                    self.passthrough_counts[why] += n
                    self._warn_once(why, f"physvla: passing the policy's action through unchanged ({why}); "
                                    "see Corrector.passthrough_counts")
            diag.passthrough = ~ok
            diag.phase = np.where(ok, diag.phase, -1).astype(np.int8)
            diag.deviation = np.where(ok, np.abs(out - a_raw).max(axis=1), 0.0)
            self.last = diag
        return out

    def _correct(self, a_raw: np.ndarray, s: PhysState, commit: np.ndarray):
        cfg, lay = self.cfg, self.layout
        nan = np.full(self.batch_size, np.nan)
        t0 = time.perf_counter()
        d_obj = xy_distance(s.eef_pos, s.obj_pos)
        d_tgt = xy_distance(s.eef_pos, s.target_pos)
        lift = s.obj_pos[:, 2] - s.obj_rest_z
        phase = detect_phase(d_obj, d_tgt, lift, cfg.delta_grasp_m, cfg.h_lift_m)
        weights = np.zeros_like(a_raw)
        r_el = r_energy = nan
        t_b = 0.0

        if cfg.mode == "temporal":
            out = self._temporal_ema(a_raw, commit)
            t_a = time.perf_counter() - t0
        else:
            a_phys = self.branch_a(a_raw, phase, s.eef_pos, s.obj_pos, d_tgt, commit=commit)
            t1 = time.perf_counter()
            t_a = t1 - t0
            if self.branch_b is not None:
                a_phys, r_el, r_energy, weights = self.branch_b(a_raw, a_phys, s)
                t_b = time.perf_counter() - t1
            out = (1.0 - cfg.cap) * a_raw + cfg.cap * a_phys  # eq. 2
            if cfg.gripper_rule == "veto" and lay.gripper is not None:
                out[:, lay.gripper] = np.where(phase == Phase.APPROACH, lay.gripper_open, out[:, lay.gripper])
        np.clip(out, lay.low, lay.high, out=out)
        diag = StepDiagnostics(phase, d_obj, d_tgt, lift, r_el, r_energy, weights, None, None, t_a, t_b)
        return out, diag

    def _temporal_ema(self, a_raw: np.ndarray, commit: np.ndarray) -> np.ndarray:
        pos = self.layout.pos_index
        alpha = self.cfg.alpha_temporal
        raw_pos = a_raw[:, pos]
        prev = np.where(self._temporal_init[:, None], self._temporal, raw_pos)
        ema = alpha * prev + (1.0 - alpha) * raw_pos
        self._temporal = np.where(commit[:, None], ema, self._temporal)
        self._temporal_init |= commit
        out = a_raw.copy()
        out[:, pos] = ema
        return out

    def _diag_passthrough(self, a_raw: np.ndarray, passthrough: np.ndarray) -> StepDiagnostics:
        b = self.batch_size
        nan = np.full(b, np.nan)
        return StepDiagnostics(
            np.full(b, -1, np.int8), nan, nan, nan, nan, nan, np.zeros_like(a_raw), np.zeros(b), passthrough
        )

    def _warn_once(self, key: str, msg: str) -> None:
        if key not in self._warned:
            self._warned.add(key)
            warnings.warn(msg, RuntimeWarning, stacklevel=3)


def _with_placeholder_rows(state: PhysState, bad: np.ndarray) -> PhysState:
    """Copy of `state` whose `bad` rows hold a harmless record (M = I, dt = 1, zeros elsewhere)."""
    flat = state.pack()
    filler = PhysState.empty(1, state.n_joints)
    filler.dt[:] = 1.0
    filler.M[:] = np.eye(state.n_joints)
    flat[bad] = filler.pack()[0]
    return PhysState.unpack(flat)
