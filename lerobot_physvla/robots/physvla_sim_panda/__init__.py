"""The MuJoCo-simulated Franka Panda (robot type `physvla_sim_panda`): config and robot, laid out
like lerobot's own robot folders (lerobot finds `SimPanda` here from `SimPandaConfig`'s module)."""

from lerobot_physvla.robots.physvla_sim_panda.config_physvla_sim_panda import SimPandaConfig
from lerobot_physvla.robots.physvla_sim_panda.physvla_sim_panda import SimPanda

__all__ = ["SimPanda", "SimPandaConfig"]
