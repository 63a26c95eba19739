"""Configuration of the MuJoCo-simulated SO-101 (robot type `physvla_sim_so101`)."""

from __future__ import annotations

from dataclasses import dataclass

from lerobot.robots.config import RobotConfig

from lerobot_physvla.robots.sim_arm import SimArmConfig


@RobotConfig.register_subclass("physvla_sim_so101")
@dataclass
class SimSO101Config(SimArmConfig):
    """A simulated SO-101 with a block on the floor, driven like lerobot's so101_follower (the
    fields: robots/sim_arm.py `SimArmConfig`; block_xyz defaults to [0.3, 0.0, 0.02]), and:

    Attributes:
        marker_camera: also report a camera "marker_cam": a 640 x 480 frame rendered every tick by
            sim/marker_scene.py's rig (3 cm ArUco markers, ids 3 and 10-13, on the block's five free faces; id 7 on a
            tile 5 cm beyond `goal_xyz`; the camera at (0.42, 0, 0.35) m looking at (0.22, 0, 0) m), for
            `--physvla.pose_source=markers`.
        goal_xyz: where the goal tile's goal is, m (with marker_camera).
    """

    marker_camera: bool = False
    goal_xyz: list[float] | None = None
