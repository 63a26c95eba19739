"""Configuration of the corrector: the action layout and every hyperparameter.

Defaults are the paper's (Table "Hyperparameter table", App. A) plus the ones SPEC adds
(h_lift, action layout, gripper rule, EL weighting and mode, eps, r0). Nothing here imports
LeRobot; the LeRobot glue turns `--physvla.*` flags into a `PhysVLAConfig`.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Literal

import numpy as np

Mode = Literal["baseline", "temporal", "phys", "phys_el"]
MODES: tuple[str, ...] = ("baseline", "temporal", "phys", "phys_el")
EL_MODES: tuple[str, ...] = ("soft", "gated", "off")
WEIGHTINGS: tuple[str, ...] = ("joint_diag", "task_space")
GRIPPER_RULES: tuple[str, ...] = ("blend", "veto")
CHUNK_MODES: tuple[str, ...] = ("all", "first")


@dataclass(frozen=True)
class ActionLayout:
    """Where each quantity sits in the env's action vector, and its units.

    Attributes:
        dim: action dimension A.
        pos: indices of the Cartesian position deltas (x, y, z), in action units.
        rot: indices of the rotation deltas (may be empty).
        gripper: index of the gripper command, or None if the env has none.
        metres_per_unit: metres of end-effector travel per action unit on the position
            channels (0.05 m for LIBERO / robosuite OSC_POSE).
        gripper_open: the gripper command value that means "open" (-1 in robosuite).
        low, high: the action space bounds (scalars, broadcast to every channel).
        absolute: False for delta layouts (the position/rotation channels are increments, so
            holding still is 0); True for absolute targets (holding still is the last target).
            The gripper channel is always treated as absolute. Used by the safe hold action that
            replaces a non-finite policy action.
    """

    dim: int
    pos: tuple[int, int, int]
    rot: tuple[int, ...] = ()
    gripper: int | None = None
    metres_per_unit: float = 0.05
    gripper_open: float = -1.0
    low: float = -1.0
    high: float = 1.0
    absolute: bool = False

    def __post_init__(self) -> None:
        used = list(self.pos) + list(self.rot) + ([self.gripper] if self.gripper is not None else [])
        if len(self.pos) != 3:
            raise ValueError(f"ActionLayout.pos needs 3 indices (x, y, z), got {self.pos}")
        if any(not 0 <= i < self.dim for i in used) or len(set(used)) != len(used):
            raise ValueError(f"ActionLayout indices {used} must be distinct and in [0, {self.dim})")
        if not self.metres_per_unit > 0:
            raise ValueError(f"metres_per_unit must be > 0, got {self.metres_per_unit}")
        if not (np.isfinite(self.low) and np.isfinite(self.high)):
            raise ValueError(f"ActionLayout bounds must be finite, got [{self.low}, {self.high}]")
        if not self.low < self.high or not self.low <= self.gripper_open <= self.high:
            raise ValueError("need low < high and gripper_open within [low, high]")

    @property
    def pos_index(self) -> np.ndarray:
        return np.asarray(self.pos, dtype=np.intp)

    def hold(self, last: np.ndarray | None = None) -> np.ndarray:
        """The safe hold action (A,): what an env executes in place of a non-finite policy action.

        Delta channels hold still with 0; absolute channels (the gripper always; every channel of
        an absolute layout) repeat `last`, the action this env executed last, or without one
        (an episode's first step) the gripper opens and other absolute channels take 0 clipped
        to the bounds.
        """
        out = np.zeros(self.dim)
        absolute = self.absolute_mask
        if last is not None and np.isfinite(last).all():
            out[absolute] = np.clip(np.asarray(last, dtype=np.float64)[absolute], self.low, self.high)
        else:
            out[absolute] = min(max(0.0, self.low), self.high)
            if self.gripper is not None:
                out[self.gripper] = self.gripper_open
        return out

    @property
    def absolute_mask(self) -> np.ndarray:
        """(A,) True on the channels that hold by repeating (see `hold`)."""
        m = np.full(self.dim, bool(self.absolute))
        if self.gripper is not None:
            m[self.gripper] = True
        return m


# robosuite / LIBERO OSC_POSE: [dx, dy, dz, drx, dry, drz, g], 0.05 m per unit, -1 = open.
LIBERO_OSC_POSE = ActionLayout(dim=7, pos=(0, 1, 2), rot=(3, 4, 5), gripper=6, metres_per_unit=0.05)
# gymnasium-robotics Fetch: [dx, dy, dz, g], 0.05 m per unit (pos_ctrl *= 0.05), +1 = open.
FETCH_4D = ActionLayout(dim=4, pos=(0, 1, 2), gripper=3, metres_per_unit=0.05, gripper_open=1.0)

LAYOUTS: dict[str, ActionLayout] = {"libero_osc_pose": LIBERO_OSC_POSE, "fetch_4d": FETCH_4D}


@dataclass
class PhysVLAConfig:
    """Every hyperparameter of the corrector, with the paper's values as defaults.

    Attributes:
        mode: baseline (identity) | temporal (uniform EMA) | phys (Branch A) | phys_el (A + B).
        layout: name of a preset in LAYOUTS, or an ActionLayout.
        cap: blender cap c of eq. (2).
        delta_grasp_m: phase envelope delta_grasp of eq. (3) and the approach veto, metres.
        h_lift_m: object height above its resting height that counts as "lifted", metres
            (SPEC; the paper never states it).
        beta: grasp-phase waypoint blend.
        grasp_offset_m: grasp waypoint p* = object position + this offset, metres (world frame).
        lift_bias_m: transport vertical lift bias Delta z+, metres.
        alpha_transport: transport-only EMA on the position channels.
        d_thresh_m: placement deceleration scale of eq. (5), metres.
        alpha_temporal: uniform EMA of the `temporal` baseline mode (position channels).
        el_mode: soft (always on, rho = 1) | gated (fires when |r_EL| > eps) | off.
        weighting: joint_diag (paper: joint weights on action entries) | task_space.
        eps_nm: gate threshold epsilon, N m.
        r0_nm: residual at which the gated weight saturates (rho = 1), N m.
        dls_damping: damping lambda of the damped least-squares Jacobian pseudo-inverse, m.
        gripper_rule: blend (paper literal: gripper goes through the capped blender) |
            veto (the approach veto sets the gripper channel to open in full).
        chunk: for (B, T, A) action chunks: correct all steps with the current state, or only
            the first (the one about to execute) and pass the rest through.
    """

    mode: str = "phys_el"
    layout: str | ActionLayout = "libero_osc_pose"
    cap: float = 0.05
    delta_grasp_m: float = 0.06
    h_lift_m: float = 0.02
    beta: float = 0.5
    grasp_offset_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    lift_bias_m: float = 0.02
    alpha_transport: float = 0.92
    d_thresh_m: float = 0.08
    alpha_temporal: float = 0.85
    el_mode: str = "soft"
    weighting: str = "joint_diag"
    eps_nm: float = 0.05
    r0_nm: float = 1.5
    dls_damping: float = 1e-2
    gripper_rule: str = "blend"
    chunk: str = "all"

    def __post_init__(self) -> None:
        self.validate()

    def validate(self) -> None:
        for name, value, allowed in (
            ("mode", self.mode, MODES),
            ("el_mode", self.el_mode, EL_MODES),
            ("weighting", self.weighting, WEIGHTINGS),
            ("gripper_rule", self.gripper_rule, GRIPPER_RULES),
            ("chunk", self.chunk, CHUNK_MODES),
        ):
            if value not in allowed:
                raise ValueError(f"physvla: unknown {name} {value!r}; choose one of {', '.join(allowed)}")
        if isinstance(self.layout, str) and self.layout not in LAYOUTS:
            raise ValueError(
                f"physvla: unknown action layout {self.layout!r}; choose one of {', '.join(LAYOUTS)} "
                "or pass an ActionLayout"
            )
        for name in ("cap", "beta", "alpha_transport", "alpha_temporal"):
            v = getattr(self, name)
            if not 0.0 <= v <= 1.0:
                raise ValueError(f"physvla: {name} must lie in [0, 1], got {v}")
        for name in ("delta_grasp_m", "h_lift_m", "d_thresh_m", "dls_damping"):
            if not getattr(self, name) > 0:
                raise ValueError(f"physvla: {name} must be > 0, got {getattr(self, name)}")
        if not 0 <= self.eps_nm < self.r0_nm:
            raise ValueError(f"physvla: need 0 <= eps_nm < r0_nm, got {self.eps_nm}, {self.r0_nm}")
        if len(self.grasp_offset_m) != 3:
            raise ValueError(f"physvla: grasp_offset_m needs 3 values, got {self.grasp_offset_m}")

    @property
    def action_layout(self) -> ActionLayout:
        return LAYOUTS[self.layout] if isinstance(self.layout, str) else self.layout

    def replace(self, **changes) -> PhysVLAConfig:
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict:
        d = dataclasses.asdict(self)
        if isinstance(self.layout, ActionLayout):
            d["layout"] = dataclasses.asdict(self.layout)
        d["grasp_offset_m"] = list(self.grasp_offset_m)
        return d

    @classmethod
    def from_dict(cls, d: dict) -> PhysVLAConfig:
        d = dict(d)
        unknown = set(d) - {f.name for f in dataclasses.fields(cls)}
        if unknown:
            raise ValueError(f"physvla: unknown config keys {sorted(unknown)}")
        if isinstance(d.get("layout"), dict):
            lay = dict(d["layout"])
            lay["pos"] = tuple(lay["pos"])
            lay["rot"] = tuple(lay.get("rot", ()))
            d["layout"] = ActionLayout(**lay)
        if "grasp_offset_m" in d:
            d["grasp_offset_m"] = tuple(d["grasp_offset_m"])
        return cls(**d)

