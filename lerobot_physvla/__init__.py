"""lerobot-physvla: inference-time physics-aware action correction for frozen LeRobot policies.

Layers, imported one way (each imports only those above it):
    core/        the algorithm: config, state, phase FSM, corrections/, branch_a, dynamics, corrector
    sim/         simulators it reads state from (LIBERO/robosuite, Lift, Fetch), scripted experts
    compat, processor/, envs/, policies/, flags, diagnostics, metrics   the LeRobot integration
    scripts/     console scripts
    plugin       what lerobot's plugin auto-import runs
"""

from lerobot_physvla import _moved

__version__ = "0.1.0"
_moved.install()
