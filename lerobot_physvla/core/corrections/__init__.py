"""Branch A's corrections, one per file, each a numba kernel with the signature of `base.py`.

    approach_veto        approach: premature-grasp veto (gripper <- open)              App. A
    grasp_guidance       grasp: blend toward the grasp waypoint p* = p_obj + offset      App. A
    transport_smoothing  transport: lift bias + EMA on the position channels             App. A
    place_deceleration   place: deceleration ramp min(1, d_tgt_xy / d_thresh)            eq. 5
    temporal_ema         the `temporal` mode's uniform EMA (the paper's smoothing foil)

Beyond the paper (docs/method.md; how each was chosen: docs/decisions/): place_redirect, release_veto,
release_assist (place), lift_assist (grasp) and rim_guide (approach, grasp).

`lerobot_physvla.core.branch_a` composes them by phase (eq. 3).
"""

from lerobot_physvla.core.corrections.approach_veto import approach_veto
from lerobot_physvla.core.corrections.grasp_guidance import grasp_guidance
from lerobot_physvla.core.corrections.place_deceleration import place_deceleration
from lerobot_physvla.core.corrections.temporal_ema import temporal_ema
from lerobot_physvla.core.corrections.transport_smoothing import transport_smoothing

__all__ = ["approach_veto", "grasp_guidance", "place_deceleration", "temporal_ema", "transport_smoothing"]
