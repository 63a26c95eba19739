"""Grasp: a pull onto the object's centre for an open hand that has settled over an object it can close
across (beyond the paper; centre_guide). centre_guide_approach runs the same kernel in the approach phase.

    whole:    2 w_o <= span: the hand closes across the object's narrower side (a can, a box, a bottle: grasped
              whole, no rim to pull to); known only from a measured scene (geometry = "scene", core/geometry.py):
              with the fixed distances it never pulls
    beside:   rho < RIM_REACH_M,  p_eef_z - p_obj_z < RIM_HEIGHT_M   (the rim zone: delta_grasp + span and
              top + RIM_HOVER_M on the scene), rho = |p_eef - p_obj|_xy, metres
    settled:  |p_eef_xy - p_eef_xy(RIM_SETTLE_STEPS steps ago)| < RIM_SETTLE_M   (rim_guide.py's test)
    open:     the policy does not command closed
    in the approach and grasp phases (the object not lifted), once beside, settled and open (then while beside
    and open, moving or not):
        a_xy <- clip(k (p_obj_xy - p_eef_xy) / metres_per_unit, -1, 1)
    k: the layout's step_gain (CENTRE_GAIN), 1 where the action sets the step's goal from the hand (LIBERO's OSC),
    below 1 where the action moves a target the hand trails (MetaWorld's mocap, 0.25), which a full-gap pull
    every step would wind up past the object.
    z and the gripper stay the policy's; the pull ends where the policy closes, the hand leaves the zone or
    the object is lifted. Unlike the rim guide's, it goes on at the centre (a zero pull holds the hand there
    against a policy that aims beside it), so the fingers close around the object's centre.
    once (centre_guide_once): a hand that leaves the zone, or closes, while pulled is not pulled again until the
    object is lifted: one pull per approach, so a policy that grasps beside the object on purpose and comes
    back to its own aim (MetaWorld's bin-picking policy, which climbs back up whenever it is held more than 2 cm
    from an aim beside the cube) is left to it.
    yield (centre_guide_yield_steps = n > 0): a pulled hand that has not gone CENTRE_DROP_M lower than its lowest
    point of the pull for n control steps, open, is let go until the object is lifted: a policy that holds still
    against the pull, neither closing nor climbing out (MetaWorld's bin-picking policy hovering over the cube,
    the shape expert whose descent stalls away from its own aim), is left to its aim.
    trailing targets (centre_guide_trailing = False): no pull at all on a layout whose step_gain is below 1 (an
    action that moves a target the hand trails, MetaWorld's mocap), where a pull at the step gain never centred a
    hand whose policy kept commanding its own aim (docs/decisions/25-centre-guide.md); the guide is then off.
    straddle (centre_guide_straddle): a settled hand already within the centre slack of the object's origin
    (rho < span / 2 - w_o) is not pulled: its open fingers clear the object's narrower side on either side
    wherever it closes across it, so its grasp needs no centring. A pull that began farther out goes on to the
    centre as before. Traced: a camera ACT that grasps LIBERO-Object's cream cheese 1.0-1.4 cm off its origin
    (slack 1.9 cm) succeeds; centred, it closed higher and lost the box (docs/decisions/25-centre-guide.md).
    clears (centre_guide_clears): an object the open hand does not clear in every orientation (its horizontal
    radius, the half-diagonal of a box, above span / 2) is not pulled: the state carries no yaw, so which of its
    sides the hand closes across is the policy's, and a centred hand closing along its length lands its fingers on
    it. Traced: LIBERO-Object's cream cheese box (r 4.06 cm, w_o 2.13 cm, 1.8 cm tall; span / 2 4.0 cm)
    under the competent camera ACT: pulled to the centre the hand stops 1.3 cm over the box's origin with the
    pads on it and the close misses; left at its own 1.9 cm off the origin it goes down to 1.0 cm and lifts
    the box. Failed its confirmation (docs/decisions/38-centre-guide-clears.md): the jittered shape expert, which
    aims beside those boxes, lost 10 pairs against the guide that centres it; experimental, in no preset.
    pose error (pose_error_m = e): the pull aims the hand at the object's pose, so e moves the grasp by up to e;
    it pulls only while e < span / 2 - w_o (CENTRE_SLACK_M: the room an open hand has on either side of the
    object across its narrower side), and leaves the hand to the policy beyond.

Traced failure: docs/decisions/25-centre-guide.md (the jittery shape expert's grasps aimed beside an object the
hand closes around, on LIBERO-Object, -Goal and -10).
"""

from numba import njit

from lerobot_physvla.core.corrections import slots
from lerobot_physvla.core.corrections.base import (EEF, METRES_PER_UNIT, OBJ, POSE_ERROR_M, X, Y, Correction, Field,
                                                   needs_authority)
from lerobot_physvla.core.corrections.rim_guide import RIM_REACH_M, _where, settled, track_hand
from lerobot_physvla.core.phase import APPROACH, GRASP

# the pose error it tolerates, m: span / 2 - w_o for an object the hand closes across, -1 (no pull) for any other
# or with no measured scene (core/geometry.py)
# the fraction of the gap it commands a step (ActionLayout.step_gain); 1.0: one pull per approach (centre_guide_once)
# control steps a pulled hand may hold its height before the pull lets go (0: never); 1.0: no pull begins within the
# slack (centre_guide_straddle); 1.0: no pull on an object the open hand does not clear in every orientation
# (centre_guide_clears, read by core/geometry.py)
PARAMS = ("CENTRE_SLACK_M", "CENTRE_GAIN", "CENTRE_ONCE", "CENTRE_YIELD", "CENTRE_STRADDLE", "CENTRE_CLEARS")
# the hand's x, y (m) over the last RIM_SETTLE_STEPS committed steps; steps recorded so far; 1.0 while it pulls;
# 1.0 once a pull has ended in this approach; the hand's lowest z in this pull (m) and the steps since it went
# CENTRE_DROP_M lower; 1.0 once a pull has let go (yield) in this approach
MEMORY = (("CENTRE_TRACK", 10), ("CENTRE_AT", 1), ("CENTRE_ON", 1), ("CENTRE_DONE", 1), ("CENTRE_LOW", 1),
          ("CENTRE_STILL", 1), ("CENTRE_LET", 1))
CENTRE_SLACK_M, CENTRE_GAIN, CENTRE_ONCE, CENTRE_YIELD, CENTRE_STRADDLE, CENTRE_CLEARS = slots.params(__file__)
CENTRE_TRACK, CENTRE_AT, CENTRE_ON, CENTRE_DONE, CENTRE_LOW, CENTRE_STILL, CENTRE_LET = slots.memory(__file__)
CENTRE_DROP_M = 0.005  # yield: a pulled hand that goes down less than this is holding its height, metres
POSE = "aims the hand at the object's pose: no pull once pose_error_m >= span / 2 - the object's narrower half-extent"
NO_PULL_M = -1.0  # CENTRE_SLACK_M where the object is not known to be grasped whole


def pulls(c) -> bool:
    """Whether the centre guide acts under configuration c: on, and on a layout the action sets the step's goal
    from the hand (step_gain 1) unless centre_guide_trailing lets it pull a trailing target too."""
    return bool(c.centre_guide and (c.centre_guide_trailing or c.action_layout.step_gain >= 1.0))


@njit(error_model="numpy")
def centre_guide(a_raw, a_phys, idx, geo, p, mem, commit):
    """x, y commanded onto the object's origin for an open hand settled beside an object it can close across
    (the approach and grasp phases); z and the gripper untouched."""
    dx, dy, rho, low_open = _where(a_raw, idx, geo, p)
    again = (p[CENTRE_ONCE] < 0.5 or mem[CENTRE_DONE] < 0.5) and mem[CENTRE_LET] < 0.5
    straddles = p[CENTRE_STRADDLE] > 0.5 and rho < p[CENTRE_SLACK_M]  # the open fingers clear it already
    on = (low_open and rho < p[RIM_REACH_M] and p[POSE_ERROR_M] < p[CENTRE_SLACK_M] and again
          and (mem[CENTRE_ON] > 0.5 or (not straddles and settled(geo, mem, CENTRE_TRACK, CENTRE_AT))))
    if on:
        for k, c in ((X, 0), (Y, 1)):
            a_phys[idx[k]] = min(max(p[CENTRE_GAIN] * (geo[OBJ + c] - geo[EEF + c]) / p[METRES_PER_UNIT], -1.0), 1.0)
    if commit:
        if mem[CENTRE_ON] > 0.5 and not on:
            mem[CENTRE_DONE] = 1.0
        if on:
            _hold_height(geo, p, mem)
        mem[CENTRE_ON] = 1.0 if on else 0.0


@njit(error_model="numpy")
def _hold_height(geo, p, mem):
    """Count the pulled steps since the hand last went CENTRE_DROP_M below its lowest point of this pull; let go
    (CENTRE_LET) after CENTRE_YIELD of them."""
    z = geo[EEF + 2]
    if mem[CENTRE_ON] < 0.5 or z < mem[CENTRE_LOW] - CENTRE_DROP_M:
        mem[CENTRE_LOW], mem[CENTRE_STILL] = z, 0.0
    else:
        mem[CENTRE_STILL] += 1.0
    if p[CENTRE_YIELD] > 0.5 and mem[CENTRE_STILL] >= p[CENTRE_YIELD]:
        mem[CENTRE_LET] = 1.0


@njit(error_model="numpy")
def centre_guide_commit(phase, geo, p, mem):
    """The pull ends once the object is lifted (transport, place), which begins a new approach; the hand's x, y are
    recorded on every committed step for the settle test."""
    if phase != APPROACH and phase != GRASP:
        mem[CENTRE_ON] = 0.0
        mem[CENTRE_DONE] = 0.0
        mem[CENTRE_LET] = 0.0
    track_hand(geo, mem, CENTRE_TRACK, CENTRE_AT)


CORRECTION = Correction("centre_guide", GRASP, 3, centre_guide,
                        values={"CENTRE_SLACK_M": lambda c, lay: NO_PULL_M,
                                "CENTRE_GAIN": lambda c, lay: lay.step_gain,
                                "CENTRE_ONCE": lambda c, lay: float(c.centre_guide_once),
                                "CENTRE_YIELD": lambda c, lay: float(c.centre_guide_yield_steps),
                                "CENTRE_STRADDLE": lambda c, lay: float(c.centre_guide_straddle),
                                "CENTRE_CLEARS": lambda c, lay: float(c.centre_guide_clears)},
                        on=pulls, commit=centre_guide_commit,
                        fields=(Field("centre_guide", bool, True, False, "an open hand settled low over an object "
                                      "it can close across is pulled onto the object's centre until it closes "
                                      "(geometry=scene; with the fixed distances it never pulls)"),
                                Field("centre_guide_once", bool, False, False, "the centre guide pulls once per "
                                      "approach: a hand that leaves the zone or closes while pulled is left to the "
                                      "policy until the object is lifted", experimental="failed its confirmation, in no preset: docs/decisions/25-centre-guide.md"),
                                Field("centre_guide_yield_steps", int, 0, 0, "the centre guide lets go of a pulled, "
                                      "open hand that has held its height (gone down under 5 mm) this many control "
                                      "steps, until the object is lifted; 0: never", experimental="failed its confirmation, in no preset: docs/decisions/25-centre-guide.md"),
                                Field("centre_guide_straddle", bool, False, False, "the centre guide begins no "
                                      "pull on a hand already within the room beside the object (closer to its "
                                      "origin than span / 2 - its narrower half-extent): its open fingers clear "
                                      "the object on either side", experimental="failed its confirmation, in no "
                                      "preset: docs/decisions/25-centre-guide.md"),
                                Field("centre_guide_clears", bool, False, False, "the centre guide pulls only an "
                                      "object the open hand clears in every orientation (its horizontal radius at "
                                      "most half the hand's opening): the state carries no yaw, so a longer one's "
                                      "grasp side is left to the policy", experimental="failed its confirmation, in "
                                      "no preset: docs/decisions/38-centre-guide-clears.md"),
                                Field("centre_guide_trailing", bool, False, True, "the centre guide also pulls "
                                      "where the action moves a target the hand trails (a layout step_gain below "
                                      "1, MetaWorld's mocap), at that gain; false: it is off on such a layout"),),
                        check=lambda c: _check(c),
                        pose=POSE)


def _check(c) -> None:
    if c.centre_guide_once and not c.centre_guide:
        raise ValueError("physvla: centre_guide_once shapes the centre guide's pull: set centre_guide=true with it, "
                         "or leave it off")
    if c.centre_guide_yield_steps < 0:
        raise ValueError(f"physvla: centre_guide_yield_steps is a count of control steps (0: never yield); got "
                         f"{c.centre_guide_yield_steps}")
    if c.centre_guide and c.action_layout.absolute:
        raise ValueError("physvla: centre_guide commands a delta layout's x, y; this layout's positions are "
                         "absolute targets: leave centre_guide off")
    if c.centre_guide:
        needs_authority(c, "centre_guide", (GRASP, APPROACH), "leave it off")
