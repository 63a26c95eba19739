"""Transport: the approach pull (approach_pull.py, which declares its parameters, memory and field) carrying the
object it lifted over the target."""

from lerobot_physvla.core.corrections.approach_pull import POSE, approach_pull
from lerobot_physvla.core.corrections.base import Correction
from lerobot_physvla.core.phase import TRANSPORT

CORRECTION = Correction("approach_pull_carry", TRANSPORT, 9, approach_pull, on=lambda c: c.approach_pull_m > 0.0,
                        pose=POSE)
