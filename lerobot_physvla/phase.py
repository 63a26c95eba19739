"""Branch A: the phase finite-state machine and its four phase corrections (paper eq. 3, 5, App. A).

Phases come from geometry alone (eq. 3):
    approach   d_obj_xy >= delta_grasp
    grasp      d_obj_xy <  delta_grasp, object not lifted
    transport  object lifted, d_tgt_xy >= delta_grasp
    place      object lifted, d_tgt_xy <  delta_grasp
where "lifted" means obj_z - obj_rest_z > h_lift (SPEC), and d_*_xy are horizontal distances
from the end-effector, in metres. All functions are batched over B envs.
"""

from __future__ import annotations

from enum import IntEnum

import numpy as np

from .config import ActionLayout, PhysVLAConfig


class Phase(IntEnum):
    APPROACH = 0
    GRASP = 1
    TRANSPORT = 2
    PLACE = 3


PHASE_NAMES = tuple(p.name.lower() for p in Phase)


def xy_distance(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Horizontal distance between (B, 3) points, metres."""
    d = a[:, :2] - b[:, :2]
    return np.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1])


def detect_phase(
    d_obj_xy: np.ndarray, d_tgt_xy: np.ndarray, lift_m: np.ndarray, delta_grasp_m: float, h_lift_m: float
) -> np.ndarray:
    """Phase per env (eq. 3), as int8 values of `Phase`.

    Args:
        d_obj_xy: (B,) end-effector to object horizontal distance, m.
        d_tgt_xy: (B,) end-effector to target horizontal distance, m.
        lift_m: (B,) object height above its resting height, m.
    """
    lifted = lift_m > h_lift_m
    near_tgt = d_tgt_xy < delta_grasp_m
    phase = np.where(lifted, np.where(near_tgt, Phase.PLACE, Phase.TRANSPORT), Phase.GRASP)
    # approach takes precedence: far from the object is approach whatever the object does.
    phase = np.where(d_obj_xy >= delta_grasp_m, Phase.APPROACH, phase)
    return phase.astype(np.int8)


class PhaseCorrector:
    """Branch A: a_phys = PhaseCorrect(phase, s_t, a_raw), with per-env transport EMA memory.

    Attributes:
        cfg: the corrector configuration (beta, lift bias, alpha_transport, d_thresh, ...).
        ema: (B, 3) transport EMA of the position channels, action units.
        in_transport: (B,) whether the previous step of that env was in transport; the EMA is
            (re)initialised from the current input on the first step of each transport segment.
    """

    def __init__(self, cfg: PhysVLAConfig, batch_size: int):
        self.cfg = cfg
        self.layout: ActionLayout = cfg.action_layout
        self.ema = np.zeros((batch_size, 3))
        self.in_transport = np.zeros(batch_size, dtype=bool)
        self._offset = np.asarray(cfg.grasp_offset_m, dtype=np.float64)
        self._lift_units = np.array([0.0, 0.0, cfg.lift_bias_m / self.layout.metres_per_unit])

    def reset(self, env_ids: np.ndarray | None = None) -> None:
        sel = slice(None) if env_ids is None else env_ids
        self.ema[sel] = 0.0
        self.in_transport[sel] = False

    def __call__(
        self,
        a_raw: np.ndarray,
        phase: np.ndarray,
        eef_pos: np.ndarray,
        obj_pos: np.ndarray,
        d_tgt_xy: np.ndarray,
        commit: np.ndarray | bool = True,
    ) -> np.ndarray:
        """Phase-corrected candidate a_phys for (B, A) raw actions, clipped to the action bounds.

        Args:
            commit: (B,) or bool; where False the EMA memory is left untouched (used for the
                not-yet-executed steps of an action chunk, and for pass-through envs).
        """
        cfg, lay = self.cfg, self.layout
        pos = lay.pos_index
        scale = lay.metres_per_unit
        raw_pos = a_raw[:, pos]
        ph = phase[:, None]

        # grasp: a_pos = beta (p* - p_eef) / scale + (1 - beta) a_raw_pos   (App. A, grasp)
        toward = (obj_pos + self._offset - eef_pos) / scale  # metres -> action units
        grasp_pos = cfg.beta * toward + (1.0 - cfg.beta) * raw_pos

        # transport: a_pos <- alpha a_pos_prev + (1 - alpha) (a_raw_pos + dz+ e_z)   (App. A, transport)
        x = raw_pos + self._lift_units
        prev = np.where(self.in_transport[:, None], self.ema, x)  # first transport step: EMA = x
        ema = cfg.alpha_transport * prev + (1.0 - cfg.alpha_transport) * x

        # place: min(1, d_tgt_xy / d_thresh) a_raw_pos   (eq. 5)
        place_pos = np.minimum(1.0, d_tgt_xy / cfg.d_thresh_m)[:, None] * raw_pos

        new_pos = np.where(
            ph == Phase.GRASP, grasp_pos, np.where(ph == Phase.TRANSPORT, ema, np.where(ph == Phase.PLACE, place_pos, raw_pos))
        )
        a = a_raw.copy()
        a[:, pos] = new_pos
        # approach: premature-grasp veto, gripper forced open.
        if lay.gripper is not None:
            a[:, lay.gripper] = np.where(phase == Phase.APPROACH, lay.gripper_open, a_raw[:, lay.gripper])

        is_tr = phase == Phase.TRANSPORT
        self.ema = np.where((is_tr & commit)[:, None], ema, self.ema)
        self.in_transport = np.where(commit, is_tr, self.in_transport)

        np.clip(a, lay.low, lay.high, out=a)
        return a
