"""Place: the carry to the target (carry_to_target.py, which declares its parameters, memory and field) carried on in
the place phase, until the object is over the target and set down: a hand in the place phase can still hold the
object centimetres off the target (a rim grasp), and a policy given its hand back there goes back to where it
remembers the target."""

from lerobot_physvla.core.corrections.base import Correction
from lerobot_physvla.core.corrections.carry_to_target import POSE, carry_to_target
from lerobot_physvla.core.phase import PLACE

CORRECTION = Correction("carry_to_target_place", PLACE, 9, carry_to_target, on=lambda c: c.carry_far_m > 0.0,
                        pose=POSE)
