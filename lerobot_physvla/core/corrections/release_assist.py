"""Place: a release for a policy that holds the object over the target and stops (beyond the
paper; release_assist_m > 0, with place_rule=release_veto).

    on target:  |p_obj_xy - p_tgt_xy| <= tol,  -tol <= p_obj_z - p_tgt_z <= h        (metres)
    a surface:  |p_tgt_z - z_rest| <= SUPPORT_M  (the target lies at the object's resting level)
    still:      max_k |a_raw_pos,k| < STILL_U while the policy commands closed         (action units)
                (assist_still=hand: |p_eef - p_eef(hold began)| <= STILL_M instead      (metres))
    after `assist_steps` control steps in a row on target, on a surface and still:
        gripper <- open, and kept open while the phase stays place
    pose error (pose_error_m = e): "on target" is judged from the poses, so the assist acts only while
    e <= tol; beyond, it cannot tell on target from off it and leaves the gripper to the policy. With
    release_assist_error_k = k > 0 the test above takes tol + k e and h + k e in place of tol and h: an object
    held on target but seen up to k e off it (a biased pose: the object and the target each off by up to e)
    still counts as on target (1 in every preset: eval/studies/pose_bias_assist.toml); 0 judges within tol alone.

Traced failure (eval/results/learned_mid, docs/method.md): weak chunked ACTs carry the bowl to the
plate, lower it to 1-4 cm above the plate's origin (or set it down on it) and then hold it there,
gripper closed and arm still, until the episode ends; on init states 0-4, 22 of act_chunk_mid's 42
failures end so. A policy that releases by itself never meets the condition (it does not stay
still with the gripper closed over the target), and a target in the air (robosuite Lift's goal
above the cube) is no surface, so a lifted object is never let go there. The release veto's
tolerance (place_tol_m) says what "on target" is, so the two rules agree: a release this rule
makes is one the veto would let through.

assist_still=hand (candidate 12): traced on the chunked ACTs under the shipped default (design block
0-4), holds that met every other condition were never let go because the policy's command is not
still inside a chunk: its z swings from -0.04 to +0.065 action units within each 10-step chunk (the
last actions of a chunk above STILL_U) while the hand moves less than 2 mm in 30 steps, so the
count restarted every chunk and never reached assist_steps. The hand's own position is what "held
still" means; the command is a proxy for it.
"""

from numba import njit

from lerobot_physvla.core.corrections import slots
from lerobot_physvla.core.corrections.base import (EEF, GRIPPER, GRIPPER_CLOSED, GRIPPER_OPEN, LIFT, OBJ, POSE_ERROR_M,
                                                   TGT, Correction, Field)
from lerobot_physvla.core.corrections.place_redirect import PLACE_TOL_M
from lerobot_physvla.core.phase import PLACE

# the highest hold, m; steps held; 1.0: judged by the hand; the pose errors the on-target test widens by
PARAMS = ("ASSIST_M", "ASSIST_STEPS", "ASSIST_STILL_HAND", "ASSIST_ERROR_K")
MEMORY = (("STALL", 1), ("ANCHOR", 3))  # steps held still over the target; the hand where the hold began, m
ASSIST_M, ASSIST_STEPS, ASSIST_STILL_HAND, ASSIST_ERROR_K = slots.params(__file__)
STALL, ANCHOR = slots.memory(__file__)

STILL_U = 0.05  # the policy commands no motion: every position channel below this, action units
STILL_M = 0.003  # assist_still=hand: the hand stays within this of where the hold began, metres
SUPPORT_M = 0.05  # the target is a surface: within this of the object's resting height, metres


@njit(error_model="numpy")
def release_assist(a_raw, a_phys, idx, geo, p, mem, commit):
    """Gripper opened once the policy has held the object still over the target for assist_steps."""
    g = idx[GRIPPER]
    if g < 0 or p[POSE_ERROR_M] > p[PLACE_TOL_M]:  # the pose cannot say "on target" within tol
        return
    if mem[STALL] >= p[ASSIST_STEPS]:  # latched: open for as long as the phase stays place
        a_phys[g] = p[GRIPPER_OPEN]
        return
    c = 0.5 * (p[GRIPPER_OPEN] + p[GRIPPER_CLOSED])  # the command's midpoint (base.py): beyond it, a close
    closed = (a_raw[g] - c) * (p[GRIPPER_OPEN] - c) < 0.0
    widen = p[ASSIST_ERROR_K] * p[POSE_ERROR_M]  # the pose error the on-target test allows for, m
    tol = p[PLACE_TOL_M] + widen
    ex, ey = geo[TGT] - geo[OBJ], geo[TGT + 1] - geo[OBJ + 1]
    dz = geo[OBJ + 2] - geo[TGT + 2]
    rest_z = geo[OBJ + 2] - geo[LIFT]
    still = True
    if p[ASSIST_STILL_HAND] > 0.5:  # the hand within STILL_M of where the hold began (its first step: still)
        if mem[STALL] > 0.0:
            moved = 0.0
            for k in range(3):
                moved += (geo[EEF + k] - mem[ANCHOR + k]) ** 2
            still = moved <= STILL_M * STILL_M
    else:
        for k in range(3):
            if abs(a_raw[idx[k]]) >= STILL_U:
                still = False
    stalled = (closed and still and ex * ex + ey * ey <= tol * tol and -tol <= dz <= p[ASSIST_M] + widen
               and abs(geo[TGT + 2] - rest_z) <= SUPPORT_M)
    if stalled and mem[STALL] + 1.0 >= p[ASSIST_STEPS]:
        a_phys[g] = p[GRIPPER_OPEN]
    if commit:
        if stalled and mem[STALL] == 0.0:
            for k in range(3):
                mem[ANCHOR + k] = geo[EEF + k]
        mem[STALL] = mem[STALL] + 1.0 if stalled else 0.0


@njit(error_model="numpy")
def release_assist_commit(phase, geo, p, mem):
    """The count of still steps starts over outside the place phase."""
    if phase != PLACE:
        mem[STALL] = 0.0


CORRECTION = Correction("release_assist", PLACE, 1, release_assist, values={
    "ASSIST_M": lambda c, lay: c.release_assist_m, "ASSIST_STEPS": lambda c, lay: c.assist_steps,
    "ASSIST_STILL_HAND": lambda c, lay: c.assist_still == "hand",
    "ASSIST_ERROR_K": lambda c, lay: c.release_assist_error_k},
    on=lambda c: c.release_assist_m > 0.0 and c.place_rule == "release_veto", commit=release_assist_commit,
    pose="judges 'on target' from the poses (within tol + release_assist_error_k x pose_error_m): off once "
         "pose_error_m > place_tol_m",
    fields=(Field("release_assist_m", float, 0.04, 0.0, "open for a hold still over the target at most this above "
                  "it, m; 0 = off"),
            Field("assist_steps", int, 10, 10, "control steps a hold lasts before the release (and the lift) assist "
                  "acts"),
            Field("assist_still", str, "hand", "action", "what makes a hold still: action (the command) | hand (the "
                  "end effector within 3 mm)"),
            Field("release_assist_error_k", float, 1.0, 0.0, "the release assist's on-target test widens by this many "
                  "pose errors (tol + k pose_error_m); 0 = within tol alone")),
    check=lambda c: _check(c))

ASSIST_STILL = ("action", "hand")


def _check(c) -> None:
    if c.assist_still not in ASSIST_STILL:
        raise ValueError(f"physvla: unknown assist_still {c.assist_still!r}; choose one of {', '.join(ASSIST_STILL)}")
    if not c.release_assist_error_k >= 0:
        raise ValueError(f"physvla: need release_assist_error_k >= 0, got {c.release_assist_error_k}")
    if not (c.release_assist_m >= 0 and c.assist_steps >= 1):
        raise ValueError(f"physvla: need release_assist_m >= 0 and assist_steps >= 1, got {c.release_assist_m}, "
                         f"{c.assist_steps}")
