"""Scripted reach -> grasp -> lift -> transport -> place expert, from privileged state.

A plain numpy state machine producing actions in a Cartesian delta layout (see
`config.ActionLayout`): it reads the end-effector, object and target positions, so it runs on
any env whose state source fills a `PhysState`. Used by the demo, the tests and (wrapped as a
LeRobot policy) the evaluation backbones.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .config import LIBERO_OSC_POSE, ActionLayout


@dataclass
class ExpertConfig:
    """Waypoint geometry (metres) and gains of the scripted expert.

    Attributes:
        hover_m: height above the object / target for the approach and transport legs.
        grasp_offset_m: grasp point relative to the object's origin (LIBERO bowls: on the rim,
            on the robot's side, so the fingers straddle the rim wall).
        place_offset_m: release point relative to the target's origin (same xy offset, so the
            object's centre ends over the target).
        close_steps: control steps spent closing the gripper before lifting.
        release_steps: control steps spent opening the gripper at the target.
        gain: action units per metre of waypoint error, divided by metres_per_unit (1 = reach
            the waypoint in one step if the controller tracked perfectly).
        tol_m: waypoint reached when the error is below this.
    """

    hover_m: float = 0.10
    grasp_offset_m: tuple[float, float, float] = (-0.045, 0.0, 0.035)
    place_offset_m: tuple[float, float, float] = (-0.045, 0.0, 0.07)
    close_steps: int = 12
    release_steps: int = 8
    gain: float = 0.6
    tol_m: float = 0.012


class PickPlaceExpert:
    """One env's scripted expert; call `reset()` at each episode start, then `act(...)` per step."""

    STAGES = ("hover_obj", "descend", "close", "lift", "hover_tgt", "lower", "release", "done")

    def __init__(self, layout: ActionLayout = LIBERO_OSC_POSE, cfg: ExpertConfig | None = None):
        self.layout = layout
        self.cfg = cfg or ExpertConfig()
        self.reset()

    def reset(self) -> None:
        self.stage = 0
        self.count = 0

    def _move(self, eef: np.ndarray, goal: np.ndarray) -> tuple[np.ndarray, float]:
        err = goal - eef
        return np.clip(self.cfg.gain * err / self.layout.metres_per_unit, -1.0, 1.0), float(np.linalg.norm(err))

    def act(self, eef_pos: np.ndarray, obj_pos: np.ndarray, target_pos: np.ndarray) -> np.ndarray:
        c, lay = self.cfg, self.layout
        a = np.zeros(lay.dim)
        close = -lay.gripper_open
        grip = lay.gripper_open
        name = self.STAGES[self.stage]
        grasp = obj_pos + np.asarray(c.grasp_offset_m)
        place = target_pos + np.asarray(c.place_offset_m)
        up = np.array([0.0, 0.0, c.hover_m])
        if name == "hover_obj":
            d, err = self._move(eef_pos, grasp + up)
            done = np.linalg.norm((grasp - eef_pos)[:2]) < c.tol_m
        elif name == "descend":
            d, err = self._move(eef_pos, grasp)
            done = err < c.tol_m
        elif name == "close":
            d, _ = self._move(eef_pos, grasp)
            grip, self.count = close, self.count + 1
            done = self.count >= c.close_steps
        elif name == "lift":
            d, err = self._move(eef_pos, np.array([*eef_pos[:2], place[2] + c.hover_m]))
            grip, done = close, err < c.tol_m
        elif name == "hover_tgt":
            d, _ = self._move(eef_pos, place + up)
            grip, done = close, np.linalg.norm((place - eef_pos)[:2]) < c.tol_m
        elif name == "lower":
            d, err = self._move(eef_pos, place)
            grip, done = close, err < c.tol_m
        elif name == "release":
            d, self.count = np.zeros(3), self.count + 1
            done = self.count >= c.release_steps
        else:
            d, done = self._move(eef_pos, place + up)[0], False
        if done:
            self.stage = min(self.stage + 1, len(self.STAGES) - 1)
            self.count = 0
        a[list(lay.pos)] = d
        if lay.gripper is not None:
            a[lay.gripper] = grip
        return np.clip(a, lay.low, lay.high)
