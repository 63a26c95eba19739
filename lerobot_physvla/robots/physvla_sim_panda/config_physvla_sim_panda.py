"""Configuration of the MuJoCo-simulated Franka Panda (robot type `physvla_sim_panda`)."""

from __future__ import annotations

from dataclasses import dataclass, field

from lerobot.robots.config import RobotConfig

from lerobot_physvla.robots.sim_arm import SimArmConfig


@RobotConfig.register_subclass("physvla_sim_panda")
@dataclass
class SimPandaConfig(SimArmConfig):
    """A simulated Panda with a block on the floor (the fields: robots/sim_arm.py
    `SimArmConfig`).

    Attributes:
        start_q: the arm's joint positions at connect(), rad (a ready pose above the floor).
    """

    block_xyz: list[float] = field(default_factory=lambda: [0.55, 0.0, 0.02])
    start_q: list[float] = field(default_factory=lambda: [0.0, 0.3, 0.0, -2.0, 0.0, 2.3, 0.785])
