"""LeRobot plugin shim.

lerobot imports every installed distribution named `lerobot_env_*` (import name = distribution
name) at the start of lerobot-eval, lerobot-train, lerobot-rollout and lerobot-replay. This one
registers the `libero_physvla` env type and the PhysVLA processor steps, and makes lerobot-eval
understand `--policy.postprocess=physvla` and `--physvla.*` (see lerobot_physvla.plugin).
"""

from lerobot_physvla.plugin import activate

activate()
