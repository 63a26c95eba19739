"""lerobot-physvla: inference-time physics-aware action correction for frozen LeRobot policies.

Layers, imported one way (each imports only those above it):
    core/        the algorithm: config, state, phase FSM, corrections/, branch_a, dynamics (+ noise_guard), corrector
    sources/     where the state comes from: MuJoCo (the dynamics oracle), robosuite / LIBERO, robot joint readings
    arms/        arm models (MuJoCo model + joint map: so101, panda) and joint targets
    sim/         simulators (LIBERO, Lift, Fetch), scenes, scripted experts
    compat, processor/, envs/, policies/, robots/, replay/, flags, diagnostics, metrics   the LeRobot integration
    scripts/     console scripts
    plugin       what lerobot's plugin auto-import runs
"""

from lerobot_physvla import _moved

__version__ = "0.1.0"
_moved.install()
