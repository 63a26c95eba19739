"""Configuration of the MuJoCo-simulated SO-101 (robot type `physvla_sim_so101`)."""

from __future__ import annotations

from dataclasses import dataclass

from lerobot.robots.config import RobotConfig

from lerobot_physvla.robots.sim_arm import SimArmConfig


@RobotConfig.register_subclass("physvla_sim_so101")
@dataclass
class SimSO101Config(SimArmConfig):
    """A simulated SO-101 with a block on the floor, driven like lerobot's so101_follower (the
    fields: robots/sim_arm.py `SimArmConfig`; block_xyz defaults to [0.3, 0.0, 0.02])."""
