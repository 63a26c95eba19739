"""Absolute joint-position targets (what SO-101 and Piper policies send) corrected through a
virtual Cartesian-delta layout.

The corrector's phases and corrections are geometric (end-effector, object, target), so a
joint-target action is read as the Cartesian move it proposes: dx = FK(q_target) - p_eef (metres,
as `VIRTUAL.metres_per_unit` units) and a gripper command g = 1 - 2 r / full_scale from the gripper
reading r (+1 close, -1 open, as robosuite). The corrector corrects [dx, g] like any delta layout;
back on the robot, a change of the Cartesian channels is mapped to the joints through the
end-effector Jacobian (damped least squares: dq = J^T (J J^T + lambda^2 I)^-1 ddx), a change of g
back to a gripper reading. Channels the corrector left alone come back exactly as the policy sent
them (no round trip).
"""

from __future__ import annotations

import numpy as np

from lerobot_physvla.core.config import ActionLayout
from lerobot_physvla.arms.model import ArmModel

# [dx, dy, dz, g]: 0.1 m per unit and bounds of +-10 units, so that no realistic tick is clipped
VIRTUAL = ActionLayout(dim=4, pos=(0, 1, 2), gripper=3, metres_per_unit=0.1, gripper_open=-1.0, low=-10.0,
                       high=10.0)


class JointTargetAdapter:
    """Maps one arm's joint targets to the virtual layout and corrected virtual actions back.

    Attributes:
        arm: the arm's model.
        damping: lambda of the damped least-squares map from a Cartesian change to joints, m.
    """

    def __init__(self, arm: ArmModel, damping: float = 1e-3):
        self.arm = arm
        self.damping = float(damping)

    def to_virtual(self, q_target_rad: np.ndarray, gripper_reading: float | None, eef_pos: np.ndarray) -> np.ndarray:
        """[dx, dy, dz, g] (VIRTUAL units) that the joint targets propose from the end-effector at eef_pos (m)."""
        out = np.zeros(4)
        out[:3] = (self.arm.eef_at(q_target_rad) - eef_pos) / VIRTUAL.metres_per_unit
        spec = self.arm.spec
        out[3] = 0.0 if gripper_reading is None else 1.0 - 2.0 * gripper_reading / spec.gripper_full_scale
        return out

    def from_virtual(self, corrected: np.ndarray, raw: np.ndarray, q_target_rad: np.ndarray,
                     gripper_reading: float | None, j_pos: np.ndarray) -> tuple[np.ndarray | None, float | None]:
        """(new joint targets in rad, or None where the Cartesian channels are unchanged; new gripper
        reading, or None where g is unchanged)."""
        q_new = None
        ddx = (corrected[:3] - raw[:3]) * VIRTUAL.metres_per_unit  # m
        if np.any(ddx != 0.0):
            a = j_pos @ j_pos.T + self.damping**2 * np.eye(3)
            q_new = q_target_rad + j_pos.T @ np.linalg.solve(a, ddx)
        g_new = None
        if gripper_reading is not None and corrected[3] != raw[3]:
            g_new = float((1.0 - corrected[3]) / 2.0 * self.arm.spec.gripper_full_scale)
        return q_new, g_new
