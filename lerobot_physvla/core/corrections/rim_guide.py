"""Approach: a pull onto the object's rim for a hand that has settled beside it, outside where a
grasp can close on it (beyond the paper; rim_guide_m > 0).

    beside:   delta_grasp <= rho < RIM_REACH_M,  p_eef_z - p_obj_z < RIM_HEIGHT_M   (approach phase; the fixed
              0.14 / 0.15 m, or the scene's: core/geometry.py)
              rho = |p_eef - p_obj|_xy, horizontal, metres
    settled:  |p_eef_xy - p_eef_xy(RIM_SETTLE_STEPS steps ago)| < RIM_SETTLE_M
    open:     the policy does not command closed
    once beside, settled and open (and then while beside and open, moving or not):
        a_xy <- clip((p_obj_xy + rim_guide_m * (p_eef - p_obj)_xy / rho - p_eef_xy) / metres_per_unit, -1, 1)
    z and the gripper stay the policy's; the pull ends where the hand enters the grasp phase
    (rho < delta_grasp), leaves the zone, or the policy closes.
    pose error (pose_error_m = e): the pull aims the hand at a point computed from the object's pose, so e
    moves the grasp by up to e; it pulls only while e < delta_grasp - rim_guide_m (the slack between the
    rim point and where the grasp phase begins), and leaves the hand to the policy beyond.
    rim_guide_into_grasp (rim_guide_grasp): a pull begun in the approach phase goes on in the grasp
    phase, the same rule, until the hand is within RIM_ARRIVE_M of rim_guide_m (rho <= rim_guide_m +
    RIM_ARRIVE_M), rises out of the zone, or the policy closes; it never begins there.

Traced failure (design block, LIBERO init states 0-4, expert_jitter, docs/decisions/17-rim-guide.md):
of the jitter expert's 9 failures there that the clean expert succeeds on (the reachable
ones), 6 are one aim draw (init state 3: an aim error of 4.9 cm) that sets the expert's rim grasp
8.5-9.8 cm from the bowl's origin, outside its wall (radius ~5.5-6.6 cm); it closes on nothing and
the phase stays approach to the end. The shipped default leaves all of them: its approach veto
lets a close through within veto_reach_m. A probe pulling such a settled hand to 4.7 cm (the
expert's rim grasp) turned 6 of the 9 and lost 1 of the jitter expert's 50 pairs, and none of the
clean or faulty experts' 100. The settle test keeps it off a hand that passes through the zone on
its way somewhere: pulling every hand that crossed it cost the clean expert 2 of its 50.

Traced failure of the pull ending at delta_grasp (design block, act_single_weak, task 3: all 5 of its
pairs failed under the shipped default and uncorrected): the ACT hovers open 5.8-6.0 cm from the
bowl's origin; the guide pulls it in to delta_grasp (6 cm), the phase turns to grasp and the pull
ends, the ACT drifts out again, and the guide pulls it back: the hand chatters at the phase boundary
and never reaches the rim. A probe (stepping the harness's scene, not committed) going on pulling
inside delta_grasp until the hand was within 5 mm of rim_guide_m turned all 5 and lost none of
tasks 3 and 9's 10 pairs. Measured as candidates 19 and 20 (docs/method.md): the learned ACTs +4.3 pp
pooled on the design block (15 / 0) with the jitter expert 0 / 2, and +0.9 pp [-0.4, +2.1] (4 / 1)
on init states 20-24; not shipped, off in every preset.
"""

from numba import njit

from lerobot_physvla.core.corrections import slots
from lerobot_physvla.core.corrections.base import (EEF, GRIPPER, GRIPPER_CLOSED, GRIPPER_OPEN, METRES_PER_UNIT, OBJ,
                                                   POSE_ERROR_M, X, Y, Correction, Field, needs_authority)
from lerobot_physvla.core.phase import APPROACH, GRASP

# the distance from the object's origin the hand is pulled to; the pose error it tolerates; the zone beside the object:
# the hand within RIM_REACH_M of its origin horizontally and below RIM_HEIGHT_M above it (m; the fixed values below, or
# the scene's: core/geometry.py)
PARAMS = ("RIM_GUIDE_M", "RIM_SLACK_M", "RIM_REACH_M", "RIM_HEIGHT_M")
# the hand's x, y (m) over the last RIM_SETTLE_STEPS committed steps; steps recorded so far; 1.0 while it pulls
MEMORY = (("RIM_TRACK", 10), ("RIM_AT", 1), ("RIM_ON", 1))
RIM_GUIDE_M, RIM_SLACK_M, RIM_REACH_M, RIM_HEIGHT_M = slots.params(__file__)
RIM_TRACK, RIM_AT, RIM_ON = slots.memory(__file__)
ON_RIM_GUIDE_GRASP = slots.P_SLOTS["ON_RIM_GUIDE_GRASP"]  # rim_guide_grasp.py goes on with this pull in the grasp phase
RIM_SETTLE_STEPS = 5  # a hand that moved under RIM_SETTLE_M in this many control steps has settled
assert MEMORY[0][1] == 2 * RIM_SETTLE_STEPS  # RIM_TRACK: x, y for each of them

RIM_REACH_FIXED_M = 0.14  # the zone beside the object: the hand within this of its origin horizontally, metres
RIM_HEIGHT_FIXED_M = 0.15  # and below this above it (a policy's hover over a bowl, ~0.135 m for the expert), metres
RIM_SETTLE_M = 0.01  # settled: moved under this in RIM_SETTLE_STEPS control steps, metres
RIM_ARRIVE_M = 0.005  # rim_guide_grasp: the pull ends within this of rim_guide_m from the origin, metres


@njit(error_model="numpy")
def rim_guide(a_raw, a_phys, idx, geo, p, mem, commit):
    """x, y commanded toward the point rim_guide_m from the object's origin on the line through the
    hand, for a hand settled beside the object, outside delta_grasp (the approach phase); z and the
    gripper untouched. Called in the approach phase only; rim_track keeps the hand's history."""
    dx, dy, rho, low_open = _where(a_raw, idx, geo, p)
    on = (low_open and 1e-9 < rho < p[RIM_REACH_M] and p[POSE_ERROR_M] < p[RIM_SLACK_M]
          and (mem[RIM_ON] > 0.5 or settled(geo, mem, RIM_TRACK, RIM_AT)))
    if on:
        _pull(a_phys, idx, geo, p, dx, dy, rho)
    if commit:
        mem[RIM_ON] = 1.0 if on else 0.0


@njit(error_model="numpy")
def _where(a_raw, idx, geo, p):
    """The hand from the object's origin (dx, dy, their length rho; metres) and whether it is low
    (under RIM_HEIGHT_M above the origin) with the policy not commanding closed."""
    dx, dy = geo[EEF] - geo[OBJ], geo[EEF + 1] - geo[OBJ + 1]
    g = idx[GRIPPER]
    c = 0.5 * (p[GRIPPER_OPEN] + p[GRIPPER_CLOSED])  # the command's midpoint (base.py): beyond it, a close
    closing = g >= 0 and (a_raw[g] - c) * (p[GRIPPER_OPEN] - c) < 0.0
    return dx, dy, (dx * dx + dy * dy) ** 0.5, geo[EEF + 2] - geo[OBJ + 2] < p[RIM_HEIGHT_M] and not closing


@njit(error_model="numpy")
def _pull(a_phys, idx, geo, p, dx, dy, rho):
    """x, y commanded toward the point rim_guide_m from the object's origin on the line through the
    hand (dx, dy: the hand from the origin, rho their length, metres), clipped to +-1 action unit."""
    for k, c in ((X, 0), (Y, 1)):
        goal = geo[OBJ + c] + p[RIM_GUIDE_M] * (dx if c == 0 else dy) / rho
        a_phys[idx[k]] = min(max((goal - geo[EEF + c]) / p[METRES_PER_UNIT], -1.0), 1.0)


@njit(error_model="numpy")
def settled(geo, mem, track, at) -> bool:
    """The hand moved under RIM_SETTLE_M (x, y) since RIM_SETTLE_STEPS control steps ago, by the track kept in
    mem[track : track + 2 RIM_SETTLE_STEPS] with its count of steps in mem[at] (`track_hand`)."""
    if mem[at] < RIM_SETTLE_STEPS:
        return False
    k = track + 2 * (int(mem[at]) % RIM_SETTLE_STEPS)
    ex, ey = geo[EEF] - mem[k], geo[EEF + 1] - mem[k + 1]
    return ex * ex + ey * ey < RIM_SETTLE_M * RIM_SETTLE_M


@njit(error_model="numpy")
def track_hand(geo, mem, track, at):
    """Record the hand's x, y into the track at mem[track] (RIM_SETTLE_STEPS entries, the count in mem[at])."""
    k = track + 2 * (int(mem[at]) % RIM_SETTLE_STEPS)
    mem[k], mem[k + 1] = geo[EEF], geo[EEF + 1]
    mem[at] += 1.0


@njit(error_model="numpy")
def rim_track(geo, mem):
    """Record the hand's x, y (every committed step, every phase) for the settle test."""
    track_hand(geo, mem, RIM_TRACK, RIM_AT)


@njit(error_model="numpy")
def rim_guide_commit(phase, geo, p, mem):
    """The pull ends outside the approach phase (unless rim_guide_grasp goes on with it in the grasp phase);
    the hand's x, y are recorded on every committed step, in every phase, for the settle test."""
    if phase != APPROACH and not (phase == GRASP and p[ON_RIM_GUIDE_GRASP] > 0.5):
        mem[RIM_ON] = 0.0
    rim_track(geo, mem)


CORRECTION = Correction("rim_guide", APPROACH, 0, rim_guide, values={"RIM_GUIDE_M": lambda c, lay: c.rim_guide_m,
                                                                         "RIM_SLACK_M": lambda c, lay: c.delta_grasp_m - c.rim_guide_m,
                                                                         "RIM_REACH_M": lambda c, lay: RIM_REACH_FIXED_M,
                                                                         "RIM_HEIGHT_M": lambda c, lay: RIM_HEIGHT_FIXED_M},
                        on=lambda c: c.rim_guide_m > 0.0, replaces=("approach_veto",), commit=rim_guide_commit,
                        fields=(Field("rim_guide_m", float, 0.047, 0.0, "a hand settled beside the object is pulled to "
                                      "this distance from its origin, m; 0 = off"),),
                        check=lambda c: _check(c),
                        pose="aims the hand at a point from the object's pose: no pull once pose_error_m >= "
                             "delta_grasp_m - rim_guide_m")


def _check(c) -> None:
    if not 0.0 <= c.rim_guide_m < c.delta_grasp_m:
        raise ValueError(f"physvla: rim_guide_m must lie in [0, delta_grasp_m = {c.delta_grasp_m}) m (the "
                         f"approach phase begins at delta_grasp_m), got {c.rim_guide_m}")
    if c.rim_guide_m > 0.0 and c.action_layout.absolute:
        raise ValueError("physvla: rim_guide_m commands a delta layout's x, y; this layout's positions are "
                         "absolute targets: leave rim_guide_m at 0")
    if c.rim_guide_m > 0.0:
        needs_authority(c, "rim_guide_m", (APPROACH,), "rim_guide_m=0")
