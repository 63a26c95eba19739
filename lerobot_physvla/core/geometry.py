"""The corrector's distances from the scene's geometry (PhysVLAConfig.geometry = "scene").

Every distance the shipped default decides by was first fitted to one object, LIBERO-Spatial's black bowl
(radius 5.4 cm, 5.2 cm tall, wider than the Panda's 8 cm opening, grasped on its rim) on one target (a plate,
6.9 cm across its narrower half). With geometry = "scene" each is instead what it stands for, measured on the
scene the state source reads (the state's `scene` field, core/state.py SCENE; sources/geometry.py), per env
and per sub-goal. With r the object's radius, w_o its narrower half-extent, top its top above its origin, w_t
the target's narrower half-extent, span the hand's widest opening, pad_w / pad_h a finger pad's half width /
height (metres):

    delta_grasp   r + pad_w              a finger pad centred farther than this from the origin is clear of
                                         the object: where a grasp can close on it (eq. 3)        bowl 6.19 cm (6)
    rim guide     r - pad_w              the pad's centre on the wall: the rim grasp of an object the hand cannot
                                         close across (2 w_o > span); no pull where it can (a can, a box, a
                                         bottle is grasped whole)                                 bowl 4.59 cm (4.7)
    centre slack  span/2 - w_o           the room an open hand has on either side of an object it closes across:
                                         the pose error the centre guide tolerates (no pull on a rim grasp, nor
                                         with the fixed distances, nor with centre_guide_clears on an object
                                         whose r exceeds span/2)                                  bowl: no pull
    rim zone      delta_grasp + span     an open hand whose far pad is within a span of the edge  bowl 14.2 cm (14)
                  top + RIM_HOVER_M      and no higher above the top than a policy's hover        bowl 15.0 cm (15)
    veto height   top + pad_h            a pad whose centre is above this misses the object       bowl 6.01 cm (6)
    veto reach    r + span/2 + pad_w     an open hand's outer pad edge farther than the object's
                                         edge: a close there cannot touch it                      bowl 10.2 cm (10)
    release tol   max(w_t - r, 0) + pad_w  the object's edge within the target's, give or take a
                                         pad's half width (how far a still hand's release lands)  bowl/plate 2.28 cm (2)
    carry reach   max(CARRY_REACH_M, hypot(r, top) + pad_w)  the object's far end is still at the hand  bowl 10 cm (10)
    open hand     span - FINGERS_M       the lift assist's hold ends short of this (lift_assist_needs_close)

(in brackets: the fixed value it replaces). A distance the configuration turns off (0) stays off, and the pose
error the corrections are told (pose_error_m) is added where it is added to the fixed ones. A state without
a measured scene (NaN: a robot, a source that reads none, a state recorded before) keeps the fixed distances.
"""

from __future__ import annotations

import math

from numba import njit

from lerobot_physvla.core.corrections.base import POSE_ERROR_M
from lerobot_physvla.core.corrections.centre_guide import CENTRE_CLEARS, CENTRE_SLACK_M, NO_PULL_M
from lerobot_physvla.core.corrections.lift_assist import FINGERS_M, LIFT_OPEN_M
from lerobot_physvla.core.corrections.place_redirect import PLACE_TOL_M
from lerobot_physvla.core.corrections.release_veto import CARRY_REACH_M
from lerobot_physvla.core.corrections.rim_guide import RIM_GUIDE_M, RIM_HEIGHT_M, RIM_REACH_M, RIM_SLACK_M

RIM_HOVER_M = 0.098  # the rim zone's top above the object's top: a policy's hover (the bowl's 0.15 m above its origin)
N_SCENE = 7  # core/state.py SCENE


@njit(error_model="numpy")
def measured(row, o_scene) -> bool:
    """The state row carries a scene (every SCENE value finite, the object's and the hand's sizes above 0)."""
    if o_scene < 0:
        return False
    for k in range(N_SCENE):
        if not math.isfinite(row[o_scene + k]):
            return False
    return row[o_scene] > 0.0 and row[o_scene + 4] > 0.0


@njit(error_model="numpy")
def scene_distances(row, o_scene, p, pe, veto_cfg, veto_out):
    """The distances of one env from its scene (module table): pe <- p with the rim guide's, the release
    tolerance's and the carry reach's slots replaced; veto_out[:] <- [veto height, veto reach] (m, the pose error
    included as for the fixed ones: corrector._float_params), where veto_cfg holds the configuration's
    [veto_height_m, veto_reach_m] (0: off, or for the reach, the whole approach phase); returns delta_grasp (m)."""
    o = o_scene
    r, w_o, top, w_t = row[o], row[o + 1], row[o + 2], row[o + 3]
    span, pad_w, pad_h = row[o + 4], row[o + 5], row[o + 6]
    e = p[POSE_ERROR_M]
    for k in range(p.shape[0]):
        pe[k] = p[k]
    d_grasp = r + pad_w
    if 2.0 * w_o > span:  # the hand cannot close across it: a rim grasp, the pad's centre on the wall
        pe[RIM_GUIDE_M] = r - pad_w
        pe[RIM_SLACK_M] = d_grasp - pe[RIM_GUIDE_M]
        pe[CENTRE_SLACK_M] = NO_PULL_M
    else:  # grasped whole: no rim to pull to; the centre guide's room on either side
        pe[RIM_SLACK_M] = -1.0
        pe[CENTRE_SLACK_M] = 0.5 * span - w_o
        if p[CENTRE_CLEARS] > 0.5 and r > 0.5 * span:  # not cleared in every orientation: no pull (centre_guide_clears)
            pe[CENTRE_SLACK_M] = NO_PULL_M
    pe[RIM_REACH_M] = d_grasp + span
    pe[RIM_HEIGHT_M] = top + RIM_HOVER_M
    if p[PLACE_TOL_M] > 0.0:
        pe[PLACE_TOL_M] = max(w_t - r, 0.0) + pad_w
    pe[CARRY_REACH_M] = max(p[CARRY_REACH_M], math.hypot(r, top) + pad_w)
    if p[LIFT_OPEN_M] < 0.0:  # lift_assist_needs_close: fingers this far apart are wide open, holding nothing
        pe[LIFT_OPEN_M] = span - FINGERS_M
    veto_out[0] = top + pad_h + e if veto_cfg[0] > 0.0 else 0.0
    if veto_cfg[1] > 0.0:
        veto_out[1] = r + 0.5 * span + pad_w + e
    else:  # the whole approach phase; told a pose error, from where the grasp phase begins (as the fixed rule)
        veto_out[1] = d_grasp + e if e > 0.0 else 0.0
    return d_grasp
