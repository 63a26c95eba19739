"""Approach: the centre guide's pull (centre_guide.py, which declares its parameters and memory) in the approach
phase, for a hand settled beside an object it can close across but outside delta_grasp of it (an aim off by more
than the object's radius and a pad)."""

from lerobot_physvla.core.corrections.base import Correction
from lerobot_physvla.core.corrections.centre_guide import POSE, centre_guide, pulls
from lerobot_physvla.core.phase import APPROACH

CORRECTION = Correction("centre_guide_approach", APPROACH, 1, centre_guide, on=pulls, pose=POSE)
