"""A scripted pick-and-place expert for the simulated SO-101, through joint targets.

The phase logic and the inverse kinematics are lerobot-env-so101's own (its `PickPlaceController`:
hover, descend, close, lift, traverse, lower, open, retreat; its top-down Levenberg-Marquardt IK
on the grasp point between the jaws), so the expert is the one that package's SO101PickPlace task
is solved with. This class reads what a LeRobot SO-101 reports (`<motor>.pos` in degrees,
`gripper.pos` 0-100, and the block's position `block.x/y/z`), integrates the controller's
Cartesian steps into a target for the grasp point, and returns the joint targets that put it
there: the action a joint-space SO-101 policy sends. It runs at lerobot-env-so101's control rate
(`CONTROL_HZ`: run the robot at that fps).

Injectable failure modes (drawn per episode from `seed`), for measuring the corrector on an arm:
    premature_close: probability that the gripper is commanded closed from the hover on, through
        the descent, as if the block were already held (the approach veto's target);
    early_release_m: probability that the gripper opens while carrying, this far (m) before the
        goal (the release veto's target); 0 = off.
    place_bias_m: a persistent place bias: the expert carries the block to the goal shifted by a
        vector of size ~ U(place_bias_m / 2, place_bias_m), direction ~ U(0, 2 pi), and sets it down
        there (a mis-estimated goal; the release veto's target too); 0 = off.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from lerobot_env_so101.ik_control import control_point, roll_to_align_axis, solve_ik
from lerobot_env_so101.mujoco_env import grasp_point_offset
from lerobot_env_so101.scripted.pick_place import Phase, PickPlaceController

from lerobot_physvla.arms.model import ARMS, resolve_mjcf

CONTROL_HZ = 10  # lerobot-env-so101's SO101PickPlace control rate (control_dt = 0.1 s)
ACTION_SCALE_M = 0.025  # its metres per unit of the controller's Cartesian step
ARM = ("shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll")
_ZERO = 1e-6  # a controller step below this is "hold": the target locks to where the grasp point is


@dataclass
class SO101ExpertConfig:
    """The expert's failure modes (all off by default).

    Attributes:
        premature_close: probability per episode that the gripper is commanded closed in the hover and
            descend phases.
        early_release: probability per episode that the gripper opens while carrying the block
            `early_release_m` before the goal (xy distance, m).
        early_release_m: see early_release.
        place_bias_m: the largest place bias, m (module docstring); 0 = off.
        seed: seed of the per-episode draws (episode k uses seed + k).
    """

    premature_close: float = 0.0
    early_release: float = 0.0
    early_release_m: float = 0.07
    place_bias_m: float = 0.0
    seed: int = 0


class SO101PickPlaceExpert:
    """Joint targets that pick the block and place it on `goal_xyz` (m, the robot's frame).

    Attributes:
        goal_xyz: where the block's centre should rest, m.
        cfg: failure modes.
        faults: the failure modes drawn for the current episode.
        phase: the controller's phase.
    """

    def __init__(self, goal_xyz, cfg: SO101ExpertConfig | None = None):
        self.goal_xyz = np.asarray(goal_xyz, dtype=np.float64).reshape(3)
        self.cfg = cfg or SO101ExpertConfig()
        scene = resolve_mjcf(ARMS["so101"].mjcf).parent / "pick_scene.xml"
        m = self.model = mujoco.MjModel.from_xml_path(str(scene))
        self.data = mujoco.MjData(m)
        self._site = m.site("gripperframe").id
        self._dofs = np.array([m.jnt_qposadr[m.joint(j).id] for j in ARM])
        self._roll = m.joint("wrist_roll").id
        self._offset = grasp_point_offset(m, self._site)
        self._ctrl_lo, self._ctrl_hi = m.actuator_ctrlrange[[m.actuator(j).id for j in ARM]].T
        self._episode = -1
        self.reset()

    def reset(self) -> None:
        """An episode starts: the controller's first phase, the faults drawn anew."""
        self._episode += 1
        rng = np.random.default_rng(self.cfg.seed + self._episode)
        self.faults = {"premature_close": bool(rng.random() < self.cfg.premature_close),
                       "early_release": bool(rng.random() < self.cfg.early_release)}
        size, angle = rng.uniform(self.cfg.place_bias_m / 2, self.cfg.place_bias_m), rng.uniform(0.0, 2 * np.pi)
        self._aim = self.goal_xyz + np.array([size * np.cos(angle), size * np.sin(angle), 0.0])  # where it places
        self._controller = PickPlaceController(action_scale=ACTION_SCALE_M)
        self._target: np.ndarray | None = None
        self._holding_zero = False
        self._released_early = False

    @property
    def phase(self) -> Phase:
        return self._controller.phase

    def __call__(self, obs: dict) -> dict:
        q = np.deg2rad([float(obs[f"{j}.pos"]) for j in ARM])
        block = np.array([float(obs[f"block.{c}"]) for c in "xyz"])
        d = self.data
        d.qpos[self._dofs] = q
        mujoco.mj_kinematics(self.model, d)
        grasp = control_point(d, self._site, self._offset)
        if self._target is None:
            self._target = grasp.copy()
        a = self._controller.act(grasp, block, self._aim)
        step = np.asarray(a[:3], dtype=np.float64) * ACTION_SCALE_M
        if np.linalg.norm(a[:3]) < _ZERO:  # lerobot-env-so101's hold: lock onto the grasp point once
            if not self._holding_zero:
                self._target = grasp.copy()
            self._holding_zero = True
        else:
            self._target = self._target + step
            self._holding_zero = False
        seed = q.copy()  # lerobot-env-so101's top-down seed: the wrist rolled so the jaws close along y
        seed[-1] = np.clip(seed[-1] + roll_to_align_axis(d, self._site, self._roll, 2, np.array([0.0, 1.0, 0.0])),
                           *self.model.jnt_range[self._roll])
        target_q = solve_ik(self.model, d, self._site, self._dofs, self._target, "levenberg_marquardt", 0.1, 20,
                            seed_q=seed, point_offset=self._offset, approach_axis=0)
        target_q = np.clip(target_q, self._ctrl_lo, self._ctrl_hi)
        grip = float(a[3])  # 0 closed .. 1 open
        phase = self._controller.phase
        if self.faults["premature_close"] and phase in (Phase.HOVER, Phase.DESCEND):
            grip = 0.0
        if (self.faults["early_release"] and phase in (Phase.TRAVERSE, Phase.LOWER)
                and np.linalg.norm(block[:2] - self.goal_xyz[:2]) < self.cfg.early_release_m):
            self._released_early = True
        if self._released_early:
            grip = 1.0
        return {**{f"{j}.pos": float(v) for j, v in zip(ARM, np.rad2deg(target_q))}, "gripper.pos": 100.0 * grip}
