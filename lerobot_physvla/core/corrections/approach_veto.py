"""Approach: the premature-grasp veto (App. A). Far from the object (d_obj_xy >= delta_grasp)
no grasp can succeed, so the gripper command is set to open.

The gripper rule `veto` (core/blend.py) also holds back a close in the grasp phase from a hand more than the veto
height above the object's origin. A close is not instantaneous: the hand keeps moving while the fingers shut, so a
policy that closes on its way down onto the object (MetaWorld's scripted shelf-place and basketball policies close
~10 cm above it, descending at ~0.8 m/s, and rise again the moment they reach it) times the close to the descent,
and a height veto delays it until the hand leaves before the fingers have shut. `timed_close` tells such a close
apart, at the step the policy begins it:

    timed:  in the grasp phase, h > veto height >= h + min(v_z, 0) * CLOSE_S   (h: the hand's height above the
            object's origin, m; v_z: its vertical velocity, m/s, J_pos[2] . qdot)
            = the hand, coming down as it moves now, is at the veto height by the time the fingers shut;
            the height veto leaves it alone for as long as the policy keeps closing;
    not:    begun elsewhere (approach, below the veto height, or hovering, rising, descending slowly above it): the
            veto judges it step by step as before, also once the hand comes down later (a close begun at rest above
            the object, e.g. a premature one, does not become timed by a descent that follows it).

CLOSE_S is `veto_close_lead_s` (0 = off, every preset: the rule as before). A state without the arm's velocity
(qdot or J_pos zero) reads v_z = 0: no close is timed, the rule as before.

`close_meets` (MEETS) asks the physics instead of a timer, at every step of a close in the grasp phase above the
veto height: will the fingers, closing from where they are now, reach the object while the hand is low enough to
hold it?

    t_meet = T_close (o - w) / (span - w)     the time left until the fingers are the object's width apart, s
                                              (T_close: the state's close_time, the source's own gripper simulated
                                              from wide open to the width w = 2 x the object's narrower half-extent;
                                              o: the fingers' opening now; span: the hand's widest opening; m)
    meets:  h + min(v_z, 0) t_meet <= veto height    the hand, moving down as it moves now, has its pads on the
                                              object by then: the height veto leaves this step's close alone
    else:   the close cannot meet the object (hovering, rising, or still too high for the fingers' speed): held

`close_meets_onset` (MEETS_ONSET) makes the same judgement once, at the step the policy begins its close, and keeps
it while the close lasts (as the timed close does): a close begun where it could not meet the object (a premature
close held since the approach, then carried down by the descent) stays held step by step.

`veto_hold_to_top` (HOLD_TO_TOP) keeps a close the height veto held at its onset (begun above the veto height, not
timed) held until the hand is at the object's top: the pads' centres level with it, half a pad on the object, rather
than their lower edges touching it (the veto height, top + pad_h). A policy that begins its close early and then
creeps down, believing it is closing, is otherwise let close with its pads' lower edges on the top of a flat box
(LIBERO's cream cheese box: top 0.89 cm over its origin) and lifts nothing. Only where the scene is measured.

A hand at rest (v_z = 0) gives the height veto exactly. A state with no close time (NaN: a robot, a source that
does not simulate its gripper, an object the hand cannot close across) or no scene leaves the height veto as it is.

Traced failure (MetaWorld shelf-place, design seeds 0-9, eval/studies/metaworld.toml): the scripted policy begins
its close ~10 cm above the block, coming down at 0.6-0.8 m/s; the height veto (6 cm) holds it 4-5 steps and the
fingers are still 5.8-6.1 cm apart (baseline: 3.5-4.5, closed on the 4 cm block) when the policy rises; the block
slips out: the clean policy 10/10 -> 1/10 under the shipped default. With CLOSE_S = 0.1 s (the Sawyer's fingers take
9 steps of 12.5 ms to close across that block) it is 10/10 again on those seeds.
"""

from numba import njit

from lerobot_physvla.core.corrections import slots
from lerobot_physvla.core.corrections.base import GRIPPER, GRIPPER_CLOSED, GRIPPER_OPEN, Correction, Field
from lerobot_physvla.core.phase import APPROACH, GRASP

# veto_close_lead_s (s, 0: off); close_meets, close_meets_onset, veto_hold_to_top (1: on)
PARAMS = ("CLOSE_S", "MEETS", "MEETS_ONSET", "HOLD_TO_TOP")
# the policy's current close: 0 none, 1 timed to the descent, 2 judged step by step, 3 judged step by step and begun
# above the veto height (held from its onset)
MEMORY = (("VETO_CLOSE", 1),)
(CLOSE_S, MEETS, MEETS_ONSET, HOLD_TO_TOP) = slots.params(__file__)
(VETO_CLOSE,) = slots.memory(__file__)


@njit(error_model="numpy")
def approach_veto(a_raw, a_phys, idx, geo, p, mem, commit):
    """gripper <- open (the layout's open value); other channels untouched."""
    if idx[GRIPPER] >= 0:
        a_phys[idx[GRIPPER]] = p[GRIPPER_OPEN]


@njit(error_model="numpy")
def timed_close(a_raw, idx, p, phase, height, v_z, veto_height, t_meet, mem, commit):
    """Whether the height veto leaves the policy's close alone (module doc): 1.0 or 0.0. height: the hand above the
    object's origin (m); v_z: its vertical velocity (m/s); veto_height: this env's (m, 0: off); t_meet: the time
    left until the fingers are the object's width apart (s; < 0 or NaN: unknown). On commit, mem[VETO_CLOSE] keeps
    the timer's judgement of the close until the policy stops closing."""
    timed = _timed(a_raw, idx, p, phase, height, v_z, veto_height, t_meet, mem, commit)
    if timed > 0.5 or not p[MEETS] > 0.5:
        return timed
    if not (phase == GRASP and veto_height > 0.0 and height > veto_height and t_meet >= 0.0):
        return 0.0
    g = idx[GRIPPER]
    c = 0.5 * (p[GRIPPER_OPEN] + p[GRIPPER_CLOSED])
    if not (a_raw[g] - c) * (p[GRIPPER_OPEN] - c) < 0.0:  # not closing
        return 0.0
    return 1.0 if height + min(v_z, 0.0) * t_meet <= veto_height else 0.0  # the pads on the object by then


@njit(error_model="numpy")
def _timed(a_raw, idx, p, phase, height, v_z, veto_height, t_meet, mem, commit):
    """The close judged once, at the step the policy begins it, and kept while it lasts: timed to the hand's descent
    by the timer (veto_close_lead_s) or, with close_meets_onset, meeting the object then (module doc); 1.0 or 0.0."""
    g = idx[GRIPPER]
    if g < 0:
        return 0.0
    c = 0.5 * (p[GRIPPER_OPEN] + p[GRIPPER_CLOSED])  # the command's midpoint (base.py): beyond it, a close
    if not (a_raw[g] - c) * (p[GRIPPER_OPEN] - c) < 0.0:  # not closing: no close to judge
        if commit:
            mem[VETO_CLOSE] = 0.0
        return 0.0
    state = mem[VETO_CLOSE]
    if state < 0.5:  # the close begins now
        timed = (p[CLOSE_S] > 0.0 and phase == GRASP and veto_height > 0.0 and height > veto_height
                 and height + min(v_z, 0.0) * p[CLOSE_S] <= veto_height)
        timed = timed or (p[MEETS_ONSET] > 0.5 and phase == GRASP and veto_height > 0.0 and height > veto_height
                          and t_meet >= 0.0 and height + min(v_z, 0.0) * t_meet <= veto_height)
        state = 1.0 if timed else (3.0 if veto_height > 0.0 and height > veto_height else 2.0)
        if commit:
            mem[VETO_CLOSE] = state
    return 1.0 if state < 1.5 else 0.0


@njit(error_model="numpy")
def held_to_top(a_raw, idx, p, mem) -> bool:
    """veto_hold_to_top: the policy's close goes on, and the height veto held it at its onset (module doc)."""
    g = idx[GRIPPER]
    if g < 0 or not p[HOLD_TO_TOP] > 0.5 or mem[VETO_CLOSE] < 2.5:
        return False
    c = 0.5 * (p[GRIPPER_OPEN] + p[GRIPPER_CLOSED])
    return (a_raw[g] - c) * (p[GRIPPER_OPEN] - c) < 0.0


CORRECTION = Correction("approach_veto", APPROACH, 0, approach_veto, values={"CLOSE_S": lambda c, lay: c.veto_close_lead_s,
                                                                       "MEETS": lambda c, lay: float(c.close_meets),
                                                                       "MEETS_ONSET": lambda c, lay: float(c.close_meets_onset),
                                                                       "HOLD_TO_TOP": lambda c, lay: float(c.veto_hold_to_top)},
                        fields=(Field("veto_close_lead_s", float, 0.0, 0.0, "the gripper veto leaves alone a close the "
                                      "policy begins above the veto height while coming down fast enough to be there "
                                      "this many seconds later (the fingers' closing time), s; 0 = off",
                                      experimental="failed its confirmation, in no preset: docs/decisions/27-timed-close.md"),
                                Field("close_meets", bool, False, False, "the gripper's height veto leaves alone a "
                                      "close whose fingers, at the speed the state's close time gives them, reach the "
                                      "object's width while the descending hand is at the veto height (module doc)",
                                      experimental="judged every step, failed its confirmation, in no preset: docs/decisions/28-close-meets.md"),
                                Field("close_meets_onset", bool, False, False, "the same judgement made once, at the "
                                      "step the policy begins its close, and kept while the close lasts: a close begun "
                                      "where it could not meet the object (a premature one) stays held"),
                                Field("veto_hold_to_top", bool, True, False, "a close the height veto holds at its "
                                      "onset stays held until the hand is at the object's top (the pads' centres level "
                                      "with it), not the pads' lower edges; a measured scene only (module doc)")),
                        check=lambda c: _check(c))


def _check(c) -> None:
    if not 0.0 <= c.veto_close_lead_s <= 1.0:
        raise ValueError(f"physvla: veto_close_lead_s is the fingers' closing time in seconds, in [0, 1]; got "
                         f"{c.veto_close_lead_s}")
