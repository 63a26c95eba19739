"""A MuJoCo-simulated arm behind LeRobot's `Robot` interface: the base of the simulated robot types
(`physvla_sim_so101`, `physvla_sim_panda`), so that the code path that drives a real arm
(lerobot-rollout, the robot action processor) runs in CI.

Observations and actions use the arm's LeRobot keys and units (arms/model.py `ArmSpec`):
"<motor>.pos" for the arm joints (degrees or radians, as the real robot reports them) and
"gripper.pos" 0 (closed) .. 100 (open); the observation also carries "block.x", "block.y",
"block.z" (the block's position, m; float features, since lerobot reads a tuple-shaped feature as a
camera) for a perception-less setup. `send_action` sets the position servos' targets and advances
the physics by 1 / fps s; `last_action` (and, with `action_log`, a JSON-lines file) holds what the
servos actually received. A subclass builds its scene (`build_scene`) and names its gripper.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field

import mujoco
import numpy as np

from lerobot.robots.config import RobotConfig
from lerobot.robots.robot import Robot

from lerobot_physvla.arms.model import ArmSpec, arm_spec

BLANK = np.zeros((8, 8, 3), np.uint8)  # the blank camera's frame (blank_camera)


@dataclass
class SimArmConfig(RobotConfig):
    """A simulated arm with a block on the floor (the fields every simulated arm shares).

    Attributes:
        fps: control rate, Hz: each `send_action` advances the physics by 1 / fps s.
        block_xyz: where the block starts, m (model frame; the arm's base at the origin).
        joint_noise_deg: std of Gaussian noise added to each arm joint reading, degrees (0: none).
        seed: seed of the reading noise.
        reading_delay_ticks: the joint readings lag the simulation by this many control ticks (a
            bus / driver delay; 0: none).
        blank_camera: also report a camera "front" (8x8 RGB, all black, not rendered): policies that
            need an image input (ACT, Diffusion) then run on this robot.
        action_log: a file to which every action the servos receive is appended (one JSON line per
            send_action), or None.
    """

    fps: int = 30
    block_xyz: list[float] = field(default_factory=lambda: [0.3, 0.0, 0.02])
    joint_noise_deg: float = 0.0
    seed: int = 0
    reading_delay_ticks: int = 0
    blank_camera: bool = False
    action_log: str | None = None


class SimArm(Robot):
    """A simulated arm (see module docstring). Subclasses set `arm` and implement `build_scene`.

    Attributes:
        spec: the arm (keys, units, joints).
        model, data: the MuJoCo scene.
        last_action: the action the servos received last (robot units), or None.
        steps: control steps taken since connect().
    """

    arm: str = ""
    gripper_joint: str = ""  # the scene joint whose position is the gripper reading

    def build_scene(self) -> tuple[mujoco.MjModel, dict[str, tuple[float, float]]]:
        """The scene (the arm with a position servo per arm joint named like the joint, a gripper,
        a free-jointed body "block") and the gripper's actuators: name -> (closed, open) target."""
        raise NotImplementedError

    def __init__(self, config: SimArmConfig):
        super().__init__(config)
        self.config = config
        self.spec: ArmSpec = arm_spec(self.arm)
        self.model, grip = self.build_scene()
        self.data = mujoco.MjData(self.model)
        m, s = self.model, self.spec
        self._motors = (*s.motors, "gripper")
        self._qpos = np.array([m.jnt_qposadr[m.joint(j).id] for j in s.joints])
        self._act = np.array([m.actuator(j).id for j in s.joints])
        self._grip_act = np.array([m.actuator(a).id for a in grip])
        self._grip_closed, self._grip_open = np.array(list(grip.values())).T
        g = m.joint(self.gripper_joint).id
        self._grip_qpos = m.jnt_qposadr[g]
        self._grip_lo, self._grip_hi = m.jnt_range[g]  # reading 0 at lo, 100 at hi
        self._block = m.body("block").id
        self._block_qpos = m.jnt_qposadr[m.joint("block").id]
        self._per_deg = 1.0 if s.unit == "deg" else np.pi / 180.0  # readings per degree
        self._substeps = max(1, round(1.0 / (config.fps * m.opt.timestep)))
        self._rng = np.random.default_rng(config.seed)
        self._connected = False
        self._past: list[np.ndarray] = []  # the last reading_delay_ticks + 1 joint positions, oldest first
        self.last_action: dict | None = None
        self.steps = 0

    @property
    def observation_features(self) -> dict:
        cam = {"front": BLANK.shape} if self.config.blank_camera else {}
        return {**{f"{k}.pos": float for k in self._motors}, **{f"block.{c}": float for c in "xyz"}, **cam}

    @property
    def action_features(self) -> dict:
        return {f"{k}.pos": float for k in self._motors}

    @property
    def is_connected(self) -> bool:
        return self._connected

    @property
    def is_calibrated(self) -> bool:
        return True

    def _state(self) -> np.ndarray:
        """Arm joint positions (rad) and the gripper joint's position, as one vector."""
        return np.append(self.data.qpos[self._qpos], self.data.qpos[self._grip_qpos])

    def connect(self, calibrate: bool = True) -> None:
        mujoco.mj_resetData(self.model, self.data)
        start = getattr(self.config, "start_q", None)  # the arm's pose at connect(), rad (else the model's zero)
        if start is not None:
            self.data.qpos[self._qpos] = start
        self.data.qpos[self._block_qpos : self._block_qpos + 3] = self.config.block_xyz
        self.data.ctrl[self._act] = self.data.qpos[self._qpos]
        self.data.ctrl[self._grip_act] = self._grip_open
        mujoco.mj_forward(self.model, self.data)
        self._connected, self.steps, self.last_action = True, 0, None
        d = self.config.reading_delay_ticks  # readings from d ticks ago (the start pose until then)
        self._past = [self._state() for _ in range(d + 1)] if d > 0 else []

    def calibrate(self) -> None:
        pass

    def configure(self) -> None:
        pass

    def get_observation(self) -> dict:
        x = self._past[0] if self._past else self._state()
        q = x[:-1] / self.spec.to_radians
        if self.config.joint_noise_deg > 0:
            q = q + self._rng.normal(0.0, self.config.joint_noise_deg * self._per_deg, q.shape)
        obs = {f"{k}.pos": float(v) for k, v in zip(self.spec.motors, q)}
        obs["gripper.pos"] = float((x[-1] - self._grip_lo) / (self._grip_hi - self._grip_lo) * 100.0)
        for c, v in zip("xyz", self.data.xpos[self._block]):
            obs[f"block.{c}"] = float(v)
        if self.config.blank_camera:
            obs["front"] = BLANK.copy()
        return obs

    def send_action(self, action: dict) -> dict:
        target = np.array([float(action[f"{k}.pos"]) for k in self._motors])
        self.data.ctrl[self._act] = target[:-1] * self.spec.to_radians
        r = np.clip(target[-1], 0.0, 100.0) / 100.0
        self.data.ctrl[self._grip_act] = self._grip_closed + r * (self._grip_open - self._grip_closed)
        mujoco.mj_step(self.model, self.data, nstep=self._substeps)
        self.steps += 1
        if self.config.reading_delay_ticks > 0:
            self._past.append(self._state())
            del self._past[: max(0, len(self._past) - self.config.reading_delay_ticks - 1)]
        self.last_action = {f"{k}.pos": float(v) for k, v in zip(self._motors, target)}
        if self.config.action_log:
            with open(self.config.action_log, "a") as f:
                f.write(json.dumps(self.last_action) + "\n")
        return dict(self.last_action)

    def disconnect(self) -> None:
        self._connected = False
