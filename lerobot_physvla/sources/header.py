"""The header of a packed state that a MuJoCo state source writes as it is, shared by the robosuite / LIBERO,
MetaWorld and SO-101 sources.

`header_rows` gives the rows (offset into the packed state, value) of valid, episode_step, dt, obj_rest_z and the
scene's geometry (core/state.py SCENE, NaN until measured); `PackedHeader` is the mixin that reads and writes the
episode step and the object's resting height through them (valid turns 1 once that height is known).
"""

from __future__ import annotations

import numpy as np

from lerobot_physvla.core.state import SCENE

N_HEADER = 5 + len(SCENE)  # valid, episode_step, dt, obj_rest_z, the scene's values, the fingers' close time
SCENE_ROWS = slice(4, 4 + len(SCENE))  # the scene's rows of the header
CLOSE_ROW = 4 + len(SCENE)  # the close time's row (core/state.py close_time)


def header_rows(f: dict[str, int], dt: float) -> np.ndarray:
    """(N_HEADER, 2) rows [offset, value] of the header, for the field offsets f (core/state.py field_offsets) and the
    control period dt (s); the episode step 0, the resting height, the scene and the close time unknown (NaN),
    valid 0."""
    return np.array([[f["valid"], 0.0], [f["episode_step"], 0.0], [f["dt"], dt], [f["obj_rest_z"], np.nan]]
                    + [[f["scene"] + k, np.nan] for k in range(len(SCENE))] + [[f["close_time"], np.nan]])


class PackedHeader:
    """The episode step and the object's resting height of a source's header rows (`self._header`, see header_rows)."""

    _header: np.ndarray

    @property
    def episode_step(self) -> int:
        return int(self._header[1, 1])

    @episode_step.setter
    def episode_step(self, value: int) -> None:
        self._header[1, 1] = value

    @property
    def obj_rest_z(self) -> float:
        return float(self._header[3, 1])

    @obj_rest_z.setter
    def obj_rest_z(self, value: float) -> None:
        self._header[3, 1] = value
        self._header[0, 1] = 1.0 if np.isfinite(value) else 0.0  # valid once the resting height is known


def pack_arm_row(src, data, row: np.ndarray, point: np.ndarray, body: int) -> np.ndarray:
    """A mocap- or servo-driven arm's packed state into row, for the MetaWorld and SO-101 sources: the oracle's
    compiled read (the arm's fields and the header), then the end-effector point (m) and its Jacobian (mj_jac at
    that point on `body`), the joints' damping added to tau, the gripper opening, the object and the target.
    src: the source (its oracle, model, _jacp, _arm_dofs, _f, _header, opening, object_pos, target_pos)."""
    import mujoco

    f = src._f
    src.oracle.read_live_into(data, row, None, src._header)
    mujoco.mj_jac(src.model, data, src._jacp, None, point, body)
    n = src.oracle.n_joints
    row[f["J_pos"] : f["J_pos"] + 3 * n] = src._jacp[:, src._arm_dofs].reshape(-1)
    row[f["tau"] : f["tau"] + n] += data.qfrc_passive[src._arm_dofs]  # the joints' damping
    row[f["eef_pos"] : f["eef_pos"] + 3] = point
    row[f["gripper"]] = src.opening(data)
    row[f["obj_pos"] : f["obj_pos"] + 3] = src.object_pos()
    row[f["target_pos"] : f["target_pos"] + 3] = src.target_pos()
    return row
