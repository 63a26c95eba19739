"""Grasp: the approach pull (approach_pull.py, which declares its parameters, memory and field) carried on in the
grasp phase, where the pulled hand comes down over the object, closes and lifts it."""

from lerobot_physvla.core.corrections.approach_pull import POSE, approach_pull
from lerobot_physvla.core.corrections.base import Correction
from lerobot_physvla.core.phase import GRASP

CORRECTION = Correction("approach_pull_grasp", GRASP, 9, approach_pull, on=lambda c: c.approach_pull_m > 0.0,
                        pose=POSE)
