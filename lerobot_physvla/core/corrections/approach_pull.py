"""Approach: a pull to where the object really is, for a policy that closes far from it (beyond the paper;
approach_pull_m > 0).

A camera policy under position shift (LIBERO-PRO's swap and temp_x / temp_y scenes) replays its demonstrations:
it goes down where the object stood in them and closes there, on the table or on another object. The
premature-grasp veto then holds its gripper open for the rest of the episode. Pulled to the object and lifted with
it, the same policy opens again at once, on its way back to where it remembers the object (traced:
docs/decisions/29-approach-pull.md). The state says where the object and the target are; this correction takes
the hand to the object and the object over the target:

    engaged:  in the approach phase, the policy commands a close with the hand rho >= approach_pull_m from the
              object (rho = |p_eef - p_obj|_xy, m); held until the place phase, or until the object, once lifted,
              is back at rest (dropped)
    then, with h = p_eef_z - p_obj_z (m), k = the layout's step_gain, every command in action units clipped to [-1, 1]:
      rise     rho > 3 NEAR_M and h < CLEAR_M - SLACK_M: a_xy = 0, a_z = k (CLEAR_M - h) / scale
      cross    rho > 3 NEAR_M:                           a_xy = k (p_obj - p_eef)_xy / scale, a_z = k (CLEAR_M - h) / scale
      descend  rho <= 3 NEAR_M:                          a_xy as cross, a_z = k (GRASP_H_M - h) / scale
      (the gripper open in all three)
      close    at GRASP_H_M: CLOSE_STEPS steps of a_xy, a_z = 0, the gripper closed; or, with
               approach_pull_stall_steps = n > 0, where the descent stalls: n control steps without coming
               STALL_DZ_M lower, at h <= STALL_MAX_H_M (an object the fingers rest on before GRASP_H_M)
      lift     then a_xy = 0, a_z = LIFT_U, the gripper closed, until the object is lifted past h_lift (after
               LIFT_STEPS steps without that, the grasp missed: back to rise; "lifted" as eq. 3 says it, so an
               object the fingers only nudged up a millimetre is not)
      carry    lifted (transport): a_xy = k (p_tgt - p_obj)_xy / scale, the hand held CARRY_M above the target's
               origin, the gripper closed
    in the place phase the place corrections and the policy take over (the policy's open is its release; the
    release veto holds one that would miss). Rotation channels stay the policy's. scale = metres per action unit.
    handback  (experimental) with approach_pull_handback, a policy that opens after the close that engaged the pull
              and then closes again nearer than approach_pull_m, before the pull's own close, has the hand back: the
              pull lets go and that close is the approach veto's business; with approach_pull_open_handback, the
              policy's open itself, nearer than approach_pull_m before the pull's own close, hands the hand back
    heading   with approach_pull_heading_u = u > 0, a far close does not engage the pull while the policy commands the
              hand toward the object at u action units or more (a_xy . (p_obj - p_eef)_xy / rho >= u): a policy on
              its way to the object that closes early is left to the approach veto; one that closes where it
              stopped, away from the object, is pulled

A policy that closes near the object (rho < approach_pull_m, the approach veto's business) is never pulled, so a
competent one on the scenes it learned is left alone: the distance is set above the largest miss a policy aiming at
this object makes (docs/decisions/29-approach-pull.md).

Pose error (pose_error_m = e): the pull aims the hand at the object's pose; it engages only while e < NEAR_M.
"""

from numba import njit

from lerobot_physvla.core.corrections import slots
from lerobot_physvla.core.corrections.base import (EEF, GRIPPER, GRIPPER_CLOSED, GRIPPER_OPEN, LIFT, METRES_PER_UNIT,
                                                   OBJ, POSE_ERROR_M, TGT, X, Y, Z, Correction, Field, needs_authority)
from lerobot_physvla.core.phase import APPROACH, GRASP, PLACE, TRANSPORT

# the close's distance from the object that engages the pull, m; step gain; the stalled descent's steps (0: off);
# the handbacks' flags; the heading, action units; eq. 3's lift threshold (h_lift + the pose error told), m
PARAMS = ("PULL_FAR_M", "PULL_GAIN", "PULL_STALL_STEPS", "PULL_HANDBACK", "PULL_OPEN_HANDBACK", "PULL_HEADING_U",
          "PULL_LIFTED_M")
# 1.0 while engaged; the stage (0 travel, 1 close, 2 lift, 3 carry); committed steps in the stage (in travel: steps
# since the descent last came STALL_DZ_M lower); the hand's height then, m; 1.0 once the policy has opened since the
# close that engaged the pull
MEMORY = (("PULL_ON", 1), ("PULL_STAGE", 1), ("PULL_STEPS", 1), ("PULL_LOW", 1), ("PULL_OPENED", 1))
(PULL_FAR_M, PULL_GAIN, PULL_STALL_STEPS, PULL_HANDBACK, PULL_OPEN_HANDBACK, PULL_HEADING_U,
 PULL_LIFTED_M) = slots.params(__file__)
PULL_ON, PULL_STAGE, PULL_STEPS, PULL_LOW, PULL_OPENED = slots.memory(__file__)
CLEAR_M = 0.12  # the travel height of the hand above the object's origin, m
GRASP_H_M = 0.01  # the hand's height above the object's origin where it closes, m
NEAR_M = 0.01  # horizontal distance from the object within which the hand descends, m
SLACK_M = 0.01  # the height band counted as reached, m
CLOSE_STEPS = 10  # control steps the gripper is given to close before the lift
LIFT_U = 1.0  # the lift's z command, action units
LIFT_STEPS = 30  # control steps of lift without the object lifted before the grasp counts as missed
CARRY_M = 0.15  # the carrying hand's height above the target's origin, m
STALL_DZ_M = 0.002  # the descent's progress that resets the stall count, m
STALL_MAX_H_M = 0.06  # the highest stalled hand (above the object's origin) that closes, m
FAR_UP_M = 1e6  # a height no hand is at: the stall count starts afresh, m


@njit(error_model="numpy")
def _toward(d_m, p):
    """A gap in metres as a clipped command: step_gain x gap / metres per unit, in [-1, 1]."""
    return min(max(p[PULL_GAIN] * d_m / p[METRES_PER_UNIT], -1.0), 1.0)


@njit(error_model="numpy")
def approach_pull(a_raw, a_phys, idx, geo, p, mem, commit):
    """x, y, z and the gripper of an engaged pull (module doc); nothing until a far close engages it."""
    g = idx[GRIPPER]
    dx, dy = geo[OBJ] - geo[EEF], geo[OBJ + 1] - geo[EEF + 1]
    rho = (dx * dx + dy * dy) ** 0.5
    on = mem[PULL_ON] > 0.5
    c = 0.5 * (p[GRIPPER_OPEN] + p[GRIPPER_CLOSED])
    closing = g >= 0 and (a_raw[g] - c) * (p[GRIPPER_OPEN] - c) < 0.0  # the policy commands a close
    if not on and closing and rho >= p[PULL_FAR_M] and p[POSE_ERROR_M] < NEAR_M:  # a close far from the object
        toward = (a_raw[idx[X]] * dx + a_raw[idx[Y]] * dy) / rho  # the policy's command toward the object, units
        on = p[PULL_HEADING_U] <= 0.0 or not toward >= p[PULL_HEADING_U]  # heading (module doc); NaN: engage
    if on and mem[PULL_ON] < 0.5:
        if commit:
            mem[PULL_ON], mem[PULL_STAGE], mem[PULL_STEPS], mem[PULL_LOW] = 1.0, 0.0, 0.0, FAR_UP_M
            mem[PULL_OPENED] = 0.0
    if not on:
        return
    h = geo[EEF + 2] - geo[OBJ + 2]
    stage = mem[PULL_STAGE]
    if p[PULL_OPEN_HANDBACK] > 0.0 and stage < 0.5 and g >= 0 and not closing and rho < p[PULL_FAR_M]:
        if commit:  # the policy opens near the object, before the pull's own close: it has the hand back
            mem[PULL_ON], mem[PULL_STAGE], mem[PULL_STEPS], mem[PULL_OPENED] = 0.0, 0.0, 0.0, 0.0
        return
    if p[PULL_HANDBACK] > 0.0 and stage < 0.5 and g >= 0:  # handback (module doc): before the pull's own close
        if not closing or rho >= p[PULL_FAR_M]:
            if commit:  # opened; or closed far again, which the pull answers as it answered the first
                mem[PULL_OPENED] = 0.0 if closing else 1.0
        elif mem[PULL_OPENED] > 0.5:  # opened, then closes again near: the policy's own grasp
            if commit:
                mem[PULL_ON], mem[PULL_STAGE], mem[PULL_STEPS], mem[PULL_OPENED] = 0.0, 0.0, 0.0, 0.0
            return
    if stage > 2.5:  # carry: the held object over the target
        a_phys[idx[X]] = _toward(geo[TGT] - geo[OBJ], p)
        a_phys[idx[Y]] = _toward(geo[TGT + 1] - geo[OBJ + 1], p)
        a_phys[idx[Z]] = _toward(geo[TGT + 2] + CARRY_M - geo[EEF + 2], p)
        if g >= 0:
            a_phys[g] = p[GRIPPER_CLOSED]
    elif stage < 0.5:  # travel: rise, cross, descend
        if rho > NEAR_M:
            rising = h < CLEAR_M - SLACK_M and rho > 3.0 * NEAR_M
            a_phys[idx[X]] = 0.0 if rising else _toward(dx, p)
            a_phys[idx[Y]] = 0.0 if rising else _toward(dy, p)
            a_phys[idx[Z]] = _toward(CLEAR_M - h, p) if rising or rho > 3.0 * NEAR_M else _toward(GRASP_H_M - h, p)
        else:
            a_phys[idx[X]], a_phys[idx[Y]], a_phys[idx[Z]] = _toward(dx, p), _toward(dy, p), _toward(GRASP_H_M - h, p)
        if g >= 0:
            a_phys[g] = p[GRIPPER_OPEN]
        if commit and rho <= NEAR_M and h <= GRASP_H_M + SLACK_M:
            mem[PULL_STAGE], mem[PULL_STEPS] = 1.0, 0.0
        elif commit and p[PULL_STALL_STEPS] > 0.0:
            if rho > 3.0 * NEAR_M or h < mem[PULL_LOW] - STALL_DZ_M:  # not descending, or still coming down
                mem[PULL_LOW], mem[PULL_STEPS] = h, 0.0
            else:
                mem[PULL_STEPS] += 1.0
                if mem[PULL_STEPS] >= p[PULL_STALL_STEPS] and h <= STALL_MAX_H_M:  # stalled: close where it is
                    mem[PULL_STAGE], mem[PULL_STEPS] = 1.0, 0.0
    else:
        a_phys[idx[X]], a_phys[idx[Y]] = 0.0, 0.0
        a_phys[idx[Z]] = 0.0 if stage < 1.5 else LIFT_U
        if g >= 0:
            a_phys[g] = p[GRIPPER_CLOSED]
        if commit:
            mem[PULL_STEPS] += 1.0
            if stage < 1.5 and mem[PULL_STEPS] >= CLOSE_STEPS:
                mem[PULL_STAGE], mem[PULL_STEPS] = 2.0, 0.0
            elif stage > 1.5 and mem[PULL_STEPS] >= LIFT_STEPS and not geo[LIFT] > p[PULL_LIFTED_M]:  # eq. 3
                mem[PULL_STAGE], mem[PULL_STEPS], mem[PULL_LOW] = 0.0, 0.0, FAR_UP_M  # missed: go round again


@njit(error_model="numpy")
def approach_pull_commit(phase, geo, p, mem):
    """A lifted object is carried (transport); the pull ends in the place phase, or where a carried object is back
    in the approach or grasp phase (dropped)."""
    if mem[PULL_ON] < 0.5:
        return
    if phase == TRANSPORT:
        mem[PULL_STAGE] = 3.0
    elif phase == PLACE or mem[PULL_STAGE] > 2.5:
        mem[PULL_ON], mem[PULL_STAGE], mem[PULL_STEPS] = 0.0, 0.0, 0.0


def _check(c) -> None:
    if c.approach_pull_m < 0.0:
        raise ValueError(f"physvla: approach_pull_m is a distance in metres (0: off); got {c.approach_pull_m}")
    if c.approach_pull_m > 0.0 and c.action_layout.absolute:
        raise ValueError("physvla: approach_pull commands a delta layout's x, y, z; this layout's positions are "
                         "absolute targets: leave approach_pull_m at 0")
    if c.approach_pull_m > 0.0:
        needs_authority(c, "approach_pull_m", (APPROACH, GRASP, TRANSPORT), "leave approach_pull_m at 0")
    if not c.approach_pull_heading_u >= 0.0:
        raise ValueError("physvla: approach_pull_heading_u is a speed in action units (0: off); got "
                         f"{c.approach_pull_heading_u}")
    if c.approach_pull_stall_steps < 0:
        raise ValueError("physvla: approach_pull_stall_steps is a count of control steps (0: off); got "
                         f"{c.approach_pull_stall_steps}")


POSE = "aims the hand at the object's pose: engages only while pose_error_m < 1 cm"
CORRECTION = Correction("approach_pull", APPROACH, 2, approach_pull,
                        values={"PULL_FAR_M": lambda c, lay: c.approach_pull_m,
                                "PULL_GAIN": lambda c, lay: lay.step_gain,
                                "PULL_STALL_STEPS": lambda c, lay: float(c.approach_pull_stall_steps),
                                "PULL_HANDBACK": lambda c, lay: float(c.approach_pull_handback),
                                "PULL_OPEN_HANDBACK": lambda c, lay: float(c.approach_pull_open_handback),
                                "PULL_HEADING_U": lambda c, lay: c.approach_pull_heading_u,
                                "PULL_LIFTED_M": lambda c, lay: c.lifted_m},
                        on=lambda c: c.approach_pull_m > 0.0, commit=approach_pull_commit,
                        fields=(Field("approach_pull_m", float, 0.10, 0.0, "a policy that closes this far (m, "
                                      "horizontally) or farther from the object is taken there: the hand rises, "
                                      "crosses over the object, comes down, closes, lifts it and carries it over the "
                                      "target; 0: off"),
                                Field("approach_pull_stall_steps", int, 0, 0, "in the approach pull's descent, a hand "
                                      "that has come no lower (by 2 mm) for this many control steps, 6 cm or less "
                                      "above the object's origin, closes where it is; 0: off (the close waits for "
                                      "1 cm)", experimental="failed its design rule, in no preset: "
                                      "docs/decisions/31-pull-stall-close.md"),
                                Field("approach_pull_handback", bool, False, False, "a policy that opens after the "
                                      "close that engaged the approach pull and closes again nearer than "
                                      "approach_pull_m, before the pull's own close, has the hand back (its close "
                                      "is then the approach veto's business); False: the pull keeps the hand",
                                      experimental="failed its design rule, in no preset: "
                                      "docs/decisions/33-pull-handback.md"),
                                Field("approach_pull_open_handback", bool, False, False, "a policy that opens, "
                                      "after the close that engaged the approach pull, nearer than approach_pull_m "
                                      "from the object and before the pull's own close, has the hand back (it goes "
                                      "on to its own grasp); False: the pull keeps the hand",
                                      experimental="failed its design rule, in no preset: "
                                      "docs/decisions/33-pull-handback.md"),
                                Field("approach_pull_heading_u", float, 0.3, 0.0, "a far close does not engage the "
                                      "approach pull while the policy commands the hand toward the object at this "
                                      "speed or more (action units): a policy on its way that closes early is left "
                                      "to the approach veto; 0: off")),
                        check=lambda c: _check(c), pose=POSE)
