"""Configuration of the MuJoCo-simulated SO-101 (robot type `physvla_sim_so101`)."""

from __future__ import annotations

from dataclasses import dataclass, field

from lerobot.robots.config import RobotConfig


@RobotConfig.register_subclass("physvla_sim_so101")
@dataclass
class SimSO101Config(RobotConfig):
    """A simulated SO-101 with a block on the floor, driven like lerobot's so101_follower.

    Attributes:
        fps: control rate, Hz: each `send_action` advances the physics by 1 / fps s.
        block_xyz: where the block starts, m (model frame; the arm's base at the origin).
        joint_noise_deg: std of Gaussian noise added to each joint reading, degrees (0: none).
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
