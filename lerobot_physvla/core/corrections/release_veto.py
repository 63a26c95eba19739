"""Place: a veto of releases that would miss the target (beyond the paper; place_rule=release_veto).

    e = p_tgt_xy - p_obj_xy,  n = |e|                          (metres)
    while the policy commands open and n > tol:
        gripper <- closed;  a_xy = gain (1 - tol / n) e / scale    (scale = m per unit)

The place redirection (`place_redirect.py`) steers the held object for the whole place phase and
so takes the horizontal channels from a policy that is still moving to its own release point; a
learned policy then waits there for the rest of the episode (docs/decisions/default-v2.md).
This correction leaves the policy alone until the one moment its error is certain to matter: it
opens the gripper with the held object's centre more than `tol` from the target's. Only then is
the release held back (gripper closed) and the object steered to within `tol`, where the
policy's own open command goes through (tol + pose_error_m: a veto holds back only a release that misses
whatever the pose's error). The vertical channel stays the policy's throughout. A
hold lasts at most `hold_steps` control steps in a row (the target may be out of reach), after
which the policy's command goes through as it is.

With `release_carry` (traced failures: docs/method.md), three more: the phase stays place while
the object carried there is still at the hand, even once it is set down (core/branch_a.py), so a
release on the table is judged too; the hand does not rise while a release is held back (the
policy, believing it has let go, retreats and would carry the object up and drop it); and a hold
steers to half the tolerance before it lets the policy's open through (not to its edge).
"""

from numba import njit

from lerobot_physvla.core.corrections import slots
from lerobot_physvla.core.corrections.base import (EEF, GRIPPER, GRIPPER_CLOSED, GRIPPER_OPEN, OBJ, POSE_ERROR_M, Z,
                                                   Correction, Field)
from lerobot_physvla.core.corrections.place_redirect import PLACE_TOL_M, steer
from lerobot_physvla.core.phase import GRASP, PLACE

# the longest hold, control steps; 1.0: release_carry; the object counts as at the hand within CARRY_REACH_M of it (3-D,
# m: CARRY_REACH_FIXED_M, or the scene's: core/geometry.py)
PARAMS = ("HOLD_STEPS", "RELEASE_CARRY", "CARRY_REACH_M")
MEMORY = (("HOLD", 1), ("CARRIED", 1))  # control steps held back in a row; 1.0: the object carried to place is at the hand
HOLD_STEPS, RELEASE_CARRY, CARRY_REACH_M = slots.params(__file__)
HOLD, CARRIED = slots.memory(__file__)
CARRY_REACH_FIXED_M = 0.10  # release_carry: the object counts as at the hand within this of it (3-D), m


@njit(error_model="numpy")
def release_veto(a_raw, a_phys, idx, geo, p, mem, commit):
    """Gripper held closed and x, y steered toward the target while the policy opens off target."""
    g = idx[GRIPPER]
    miss = False  # the policy opens with the object's centre beyond tol of the target's
    carry = p[RELEASE_CARRY] > 0.5
    c = 0.5 * (p[GRIPPER_OPEN] + p[GRIPPER_CLOSED])  # the command's midpoint (base.py): open side beyond it
    if g >= 0 and (a_raw[g] - c) * (p[GRIPPER_OPEN] - c) > 0.0:
        tol = p[PLACE_TOL_M]
        if carry and mem[HOLD] > 0.0:
            tol = 0.5 * tol  # a hold under way steers to half the tolerance
        tol += p[POSE_ERROR_M]  # a release is held back only where it misses whatever the pose's error
        k, ex, ey = steer(geo, p, tol)
        miss = k > 0.0
        if miss and mem[HOLD] < p[HOLD_STEPS]:
            a_phys[g] = p[GRIPPER_CLOSED]
            a_phys[idx[0]] = k * ex
            a_phys[idx[1]] = k * ey
            if carry and a_phys[idx[Z]] > 0.0:
                a_phys[idx[Z]] = 0.0  # the hand does not rise while it holds the release back
    if commit:  # count held (or yielded) steps in a row; anything else starts over
        mem[HOLD] = min(mem[HOLD] + 1.0, p[HOLD_STEPS]) if miss else 0.0


@njit(error_model="numpy")
def release_veto_commit(phase, geo, p, mem):
    """The count of held steps starts over outside the place phase."""
    if phase != PLACE:
        mem[HOLD] = 0.0


@njit(error_model="numpy")
def carried_phase(ph, g, p, mem, commit):
    """release_carry: an object carried to the place phase stays in place while it is at the hand
    (within CARRY_REACH_M, 3-D), even when it is set down (its lift below h_lift would make eq. 3
    say grasp); the memory ends when the object leaves the hand."""
    dx, dy, dz = g[OBJ] - g[EEF], g[OBJ + 1] - g[EEF + 1], g[OBJ + 2] - g[EEF + 2]
    at_hand = dx * dx + dy * dy + dz * dz < p[CARRY_REACH_M] * p[CARRY_REACH_M]
    carried = at_hand and (ph == PLACE or mem[CARRIED] > 0.5)
    if commit:
        mem[CARRIED] = 1.0 if carried else 0.0
    return PLACE if carried and ph == GRASP else ph


CORRECTION = Correction("release_veto", PLACE, 0, release_veto, values={
    "HOLD_STEPS": lambda c, lay: c.hold_steps, "RELEASE_CARRY": lambda c, lay: c.release_carry,
    "CARRY_REACH_M": lambda c, lay: CARRY_REACH_FIXED_M},
    on=lambda c: c.place_rule == "release_veto", commit=release_veto_commit,
    pose="holds back only a release beyond its tolerance + pose_error_m",
    fields=(Field("hold_steps", int, 40, 40, "the longest a release is held back in a row, control steps"),
            Field("release_carry", bool, True, False, "the phase stays place while the carried object is at the "
                  "hand, the hand does not rise during a hold, a hold steers to half the tolerance")),
    check=lambda c: _check(c))


def _check(c) -> None:
    if not c.hold_steps >= 0:
        raise ValueError(f"physvla: hold_steps must be >= 0, got {c.hold_steps}")
