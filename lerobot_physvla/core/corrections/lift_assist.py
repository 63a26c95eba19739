"""Grasp: a lift for a policy that holds the object and stays still without lifting it (beyond the
paper; lift_assist_u > 0).

    holding:  gripper commanded closed, fingers stopped >= FINGERS_M apart     (something between them;
              with lift_assist_needs_close, on a measured scene, also >= FINGERS_M short of the hand's span:
              fingers the gripper veto holds wide open hold nothing)
    still:    |p_eef - p_eef(hold began)| <= STILL_M and |fingers - fingers(hold began)| <= FINGER_STILL_M
    at rest:  p_obj_z - z_rest >= -(REST_M + e)          (lift_assist_at_rest only: not carried below its rest;
                                                           e = pose_error_m, so an error alone never says "below")
    after `assist_steps` control steps in a row holding and still (in the grasp phase, so not lifted):
        a_z <- max(a_raw_z, lift_assist_u)                                      (action units)
    until the phase leaves grasp (the object is lifted past h_lift), the policy commands open, or
    the hand has risen RISE_M above where the hold began (the object did not follow: spent until
    the policy opens or the phase changes)

Traced failure (design block, LIBERO init states 0-4, docs/decisions/15-lift-assist.md): the weaker
single-step ACTs close on the bowl's rim and then hold it, gripper closed, the hand still within
a millimetre or two, commanding z ~ -0.02 action units, until the episode ends; the fingers stop
7-15 mm apart where their teacher's rim grasps stop at ~4 mm, a hold their demonstrations never
showed. Of act_single_mid's 19 failures on the tasks its teacher solves, 12 end so (T2, T3, T7); of
act_single_weak's 24, 11 (T0, T1, T8). A policy that lifts by itself never meets the condition for
assist_steps steps; fingers closed on nothing (~1 mm) are not a hold.

lift_assist_at_rest (candidate 16): traced on candidate 15's one lost design-block pair (act_chunk,
task 9 / init state 2): the ACT carries the bowl from where it rests down to a plate 20 cm lower,
so eq. 3 (lift below h_lift) calls the carry grasp; the hand paused holding it 20 cm below the bowl's
rest, and the assist raised it for 22 steps: candidate 12's run of that episode succeeded at step
272, candidate 15's had not by the horizon (280).
"""

from numba import njit

from lerobot_physvla.core.corrections import slots
from lerobot_physvla.core.corrections.base import (EEF, FINGERS, GRIPPER, GRIPPER_CLOSED, GRIPPER_OPEN, LIFT,
                                                   POSE_ERROR_M, Z, Correction, Field)
from lerobot_physvla.core.corrections.release_assist import STILL_M
from lerobot_physvla.core.phase import GRASP

# the z command, action units; 1.0: at rest only; steps held; the opening at which the hand is open, holding nothing
# (m; 0: not judged; -1: lift_assist_needs_close, from the scene: core/geometry.py writes span - FINGERS_M)
PARAMS = ("LIFT_ASSIST_U", "LIFT_AT_REST", "LIFT_ASSIST_STEPS", "LIFT_OPEN_M")
# steps held still unlifted (>= the steps: lifting; -1: spent); the hand (m, xyz) and the fingers' opening (m) where it began
MEMORY = (("LIFT_STALL", 1), ("LIFT_ANCHOR", 4))
LIFT_ASSIST_U, LIFT_AT_REST, ASSIST_STEPS, LIFT_OPEN_M = slots.params(__file__)
LIFT_STALL, LIFT_ANCHOR = slots.memory(__file__)

FINGERS_M = 0.0025  # fingers stopped at least this far apart: they hold something, metres
FINGER_STILL_M = 0.001  # and have stopped closing: within this of their opening where the hold began, metres
RISE_M = 0.08  # the hand rose this far above where the hold began and the object stayed: stop, metres
REST_M = 0.01  # lift_assist_at_rest: the object no more than this below its resting height, metres


@njit(error_model="numpy")
def lift_assist(a_raw, a_phys, idx, geo, p, mem, commit):
    """z command raised to lift_assist_u once the policy has held the object still, unlifted, for
    assist_steps control steps; every other channel untouched."""
    g, z = idx[GRIPPER], idx[Z]
    if g < 0:
        return
    c = 0.5 * (p[GRIPPER_OPEN] + p[GRIPPER_CLOSED])  # the command's midpoint (base.py): beyond it, a close
    if not (a_raw[g] - c) * (p[GRIPPER_OPEN] - c) < 0.0:  # the policy commands open: no hold, the count restarts
        if commit:
            mem[LIFT_STALL] = 0.0
        return
    n = mem[LIFT_STALL]
    if n < 0.0:  # spent: this hold was lifted RISE_M and the object stayed
        return
    if n >= p[ASSIST_STEPS]:  # lifting
        if geo[EEF + 2] - mem[LIFT_ANCHOR + 2] <= RISE_M:
            a_phys[z] = max(a_raw[z], p[LIFT_ASSIST_U])
        elif commit:
            mem[LIFT_STALL] = -1.0
        return
    held = geo[FINGERS] >= FINGERS_M and (p[LIFT_AT_REST] < 0.5 or geo[LIFT] >= -(REST_M + p[POSE_ERROR_M]))
    held = held and not (p[LIFT_OPEN_M] > 0.0 and geo[FINGERS] >= p[LIFT_OPEN_M])  # held open: no hold
    if held and n > 0.0:  # its first step is still by definition
        moved = 0.0
        for k in range(3):
            moved += (geo[EEF + k] - mem[LIFT_ANCHOR + k]) ** 2
        held = moved <= STILL_M * STILL_M and abs(geo[FINGERS] - mem[LIFT_ANCHOR + 3]) <= FINGER_STILL_M
    if held and n + 1.0 >= p[ASSIST_STEPS]:
        a_phys[z] = max(a_raw[z], p[LIFT_ASSIST_U])
    if commit:
        if held and n == 0.0:
            for k in range(3):
                mem[LIFT_ANCHOR + k] = geo[EEF + k]
            mem[LIFT_ANCHOR + 3] = geo[FINGERS]
        mem[LIFT_STALL] = n + 1.0 if held else 0.0


@njit(error_model="numpy")
def lift_assist_commit(phase, geo, p, mem):
    """The count starts over outside the grasp phase."""
    if phase != GRASP:
        mem[LIFT_STALL] = 0.0


CORRECTION = Correction("lift_assist", GRASP, 1, lift_assist, values={
    "LIFT_ASSIST_U": lambda c, lay: c.lift_assist_u, "LIFT_AT_REST": lambda c, lay: c.lift_assist_at_rest,
    "LIFT_ASSIST_STEPS": lambda c, lay: c.assist_steps, "LIFT_OPEN_M": lambda c, lay: -1.0 if c.lift_assist_needs_close else 0.0},
    on=lambda c: c.lift_assist_u > 0.0, commit=lift_assist_commit,
    pose="its at-rest check allows pose_error_m more below the rest (the lift it commands is the hand's own)",
    fields=(Field("lift_assist_u", float, 0.5, 0.0, "the z command a still, closed, unlifted hold is raised to, "
                  "action units; 0 = off"),
            Field("lift_assist_at_rest", bool, True, False, "lift only an object at its resting height or above"),
            Field("lift_assist_needs_close", bool, True, False, "a hold is fingers closed from wide open: a hand "
                  "the gripper veto holds open is not lifted; a measured scene only (module doc)")),
    check=lambda c: _check(c))


def _check(c) -> None:
    if not 0.0 <= c.lift_assist_u <= 1.0:
        raise ValueError(f"physvla: lift_assist_u must lie in [0, 1] action units, got {c.lift_assist_u}")
    if c.lift_assist_u > 0.0 and c.action_layout.absolute:
        raise ValueError("physvla: lift_assist_u raises a delta layout's z command; this layout's positions are "
                         "absolute targets: leave lift_assist_u at 0")
    if c.lift_assist_u > 0.0 and c.caps[1] == 0.0:
        raise ValueError("physvla: lift_assist_u acts with the grasp phase's authority, which is 0 here: set "
                         "phase_caps with a grasp entry above 0 (e.g. phase_caps=(0, 1, 0, 1) with beta=0: the "
                         "paper's grasp guidance then leaves the action as it is)")
    chunk = tuple(c.chunk_phase_caps)
    if c.lift_assist_u > 0.0 and chunk and chunk[1] == 0.0:
        raise ValueError("physvla: lift_assist_u acts with the grasp phase's authority, which is 0 in "
                         "chunk_phase_caps: set its grasp entry above 0, or lift_assist_u=0")
