"""The MuJoCo-simulated SO-101 (robot type `physvla_sim_so101`): config and robot, laid out like
lerobot's own robot folders (lerobot finds `SimSO101` here from `SimSO101Config`'s module)."""

from lerobot_physvla.robots.physvla_sim_so101.config_physvla_sim_so101 import SimSO101Config
from lerobot_physvla.robots.physvla_sim_so101.physvla_sim_so101 import SimSO101

__all__ = ["SimSO101", "SimSO101Config"]
