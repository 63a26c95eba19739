"""Transport: an object the policy lowers far from the target, carried over the target instead (beyond the paper;
carry_far_m > 0).

A camera policy under position shift (LIBERO-PRO's swap) can grasp the right object and still carry it to where its
demonstrations had the target: it lifts the bowl, moves a few centimetres and sets it down 15-19 cm off the plate,
before it opens (traced: eval/results/camera_spatial_diffusion/transcripts.md). The place phase is never entered, so
the release veto has nothing to hold. The state says where the target is; this correction takes the object there:

    n = |p_tgt - p_obj|_xy (m)
    engaged:  in the transport or place phase, the policy lowers the object it holds (a_z < -LOWER_U) or opens,
              with n >= carry_far_m + pose_error_m; held until the object is set down (the approach or grasp phase)
    then, k = the layout's step_gain, every command in action units clipped to [-1, 1]:
      carry   n > place_tol_m: a_xy = k (p_tgt - p_obj)_xy / scale, the hand held CARRY_HEIGHT_M above the target's
              origin (with carry_clear_m = c > 0: never lowering the object below c over where it rested, for an
              object lifted from a shelf above the target), the gripper closed
      set     once n <= place_tol_m: a_xy as carry, a_z = -k lift / scale (lift = the object's height above its rest,
              m), the gripper closed down to SET_LIFT_M, then open: the corrector sets the object down on the target
    Rotation channels stay the policy's. scale = metres per action unit.

It goes on through the place phase (carry_to_target_place.py), which a hand holding a bowl by its rim enters with the
bowl still centimetres off the target (docs/decisions/30-carry-to-target.md), and ends where the object is back at
rest and the hand has left it (the approach or grasp phase). A policy that lowers the object within carry_far_m of
the target is left alone. Needs the transport and place phases' authority (phase_caps).
"""

from numba import njit

from lerobot_physvla.core.corrections import slots
from lerobot_physvla.core.corrections.base import (EEF, GRIPPER, GRIPPER_CLOSED, GRIPPER_OPEN, LIFT, METRES_PER_UNIT,
                                                   OBJ, POSE_ERROR_M, TGT, X, Y, Z, Correction, Field, needs_authority)
from lerobot_physvla.core.corrections.place_redirect import PLACE_TOL_M
from lerobot_physvla.core.phase import APPROACH, GRASP, PLACE, TRANSPORT

# the object's distance from the target that engages it, m; step gain; the least height over its rest it is carried at
# (m; 0: off)
PARAMS = ("CARRY_FAR_M", "CARRY_GAIN", "CARRY_CLEAR_M")
MEMORY = (("CARRY_ON", 1),)  # 1.0 while carrying, 2.0 while setting down, 0.0 off
CARRY_FAR_M, CARRY_GAIN, CARRY_CLEAR_M = slots.params(__file__)
(CARRY_ON,) = slots.memory(__file__)
CARRY_HEIGHT_M = 0.15  # the carrying hand's height above the target's origin, m (the approach pull's carry)
LOWER_U = 0.25  # a z command below -LOWER_U (action units) lowers the object
SET_LIFT_M = 0.03  # the object's height above its rest at which the set-down opens the gripper, m
POSE = "engages only where the object is carry_far_m + pose_error_m or farther from the target"


@njit(error_model="numpy")
def _toward(d_m, p):
    """A gap in metres as a clipped command: step_gain x gap / metres per unit, in [-1, 1]."""
    return min(max(p[CARRY_GAIN] * d_m / p[METRES_PER_UNIT], -1.0), 1.0)


@njit(error_model="numpy")
def carry_to_target(a_raw, a_phys, idx, geo, p, mem, commit):
    """x, y, z and the gripper of an engaged carry (module doc); nothing until the policy lowers or opens far off."""
    g = idx[GRIPPER]
    if g < 0:
        return
    ex, ey = geo[TGT] - geo[OBJ], geo[TGT + 1] - geo[OBJ + 1]
    n = (ex * ex + ey * ey) ** 0.5
    on = mem[CARRY_ON] > 0.5
    setting = mem[CARRY_ON] > 1.5
    if not on and n >= p[CARRY_FAR_M] + p[POSE_ERROR_M]:
        c = 0.5 * (p[GRIPPER_OPEN] + p[GRIPPER_CLOSED])
        opens = (a_raw[g] - c) * (p[GRIPPER_OPEN] - c) > 0.0
        on = opens or a_raw[idx[Z]] < -LOWER_U
        if on and commit:
            mem[CARRY_ON] = 1.0
    if not on:
        return
    a_phys[idx[X]] = _toward(ex, p)
    a_phys[idx[Y]] = _toward(ey, p)
    setting = setting or n <= p[PLACE_TOL_M]
    if setting:
        a_phys[idx[Z]] = _toward(-geo[LIFT], p)
        a_phys[g] = p[GRIPPER_CLOSED] if geo[LIFT] > SET_LIFT_M else p[GRIPPER_OPEN]
        if commit:
            mem[CARRY_ON] = 2.0
    else:
        dz = geo[TGT + 2] + CARRY_HEIGHT_M - geo[EEF + 2]
        if p[CARRY_CLEAR_M] > 0.0:
            dz = max(dz, p[CARRY_CLEAR_M] - geo[LIFT])  # not below carry_clear_m over its rest
        a_phys[idx[Z]] = _toward(dz, p)
        a_phys[g] = p[GRIPPER_CLOSED]


@njit(error_model="numpy")
def carry_to_target_commit(phase, geo, p, mem):
    """The carry ends where the object is set down and left (the approach or grasp phase)."""
    if phase == APPROACH or phase == GRASP:
        mem[CARRY_ON] = 0.0


def _check(c) -> None:
    if c.carry_far_m < 0.0:
        raise ValueError(f"physvla: carry_far_m is a distance in metres (0: off); got {c.carry_far_m}")
    if c.carry_far_m > 0.0 and c.action_layout.absolute:
        raise ValueError("physvla: carry_far_m commands a delta layout's x, y, z; this layout's positions are "
                         "absolute targets: leave carry_far_m at 0")
    if not c.carry_clear_m >= 0.0:
        raise ValueError(f"physvla: carry_clear_m is a height in metres (0: off); got {c.carry_clear_m}")
    if c.carry_far_m > 0.0:
        needs_authority(c, "carry_far_m", (TRANSPORT, PLACE), "leave carry_far_m at 0")


CORRECTION = Correction("carry_to_target", TRANSPORT, 10, carry_to_target,
                        values={"CARRY_FAR_M": lambda c, lay: c.carry_far_m,
                                "CARRY_GAIN": lambda c, lay: lay.step_gain,
                                "CARRY_CLEAR_M": lambda c, lay: c.carry_clear_m},
                        on=lambda c: c.carry_far_m > 0.0, commit=carry_to_target_commit,
                        fields=(Field("carry_far_m", float, 0.10, 0.0, "in transport, an object the policy lowers (or "
                                      "lets go of) this far (m, horizontally) or farther from the target is carried "
                                      "over the target instead, 15 cm above it, and set down there; 0: off"),
                                Field("carry_clear_m", float, 0.05, 0.0, "the carry to the target never lowers the "
                                      "object below this height (m) over where it rested before the lift (an object "
                                      "lifted from a shelf above the target); 0: off")),
                        check=lambda c: _check(c), pose=POSE)
