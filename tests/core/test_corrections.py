"""Each Branch A correction on its own (one shared signature), and the compiled cache's safety."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from lerobot_physvla.core import branch_a
from lerobot_physvla.core.config import FETCH_4D, LIBERO_OSC_POSE, PhysVLAConfig
from lerobot_physvla.core.corrections import (
    approach_veto, grasp_guidance, place_deceleration, temporal_ema, transport_smoothing,
)
from lerobot_physvla.core.corrections import channel_index, params
from lerobot_physvla.core.corrections.base import D_TGT_XY, EEF, N_GEO, N_MEM, OBJ
from lerobot_physvla.core.corrections.transport_smoothing import ACTIVE, EMA

PKG = Path(branch_a.__file__).resolve().parents[2]


def ctx(layout=LIBERO_OSC_POSE, eef=(0.0, 0.0, 1.0), obj=(0.02, -0.01, 0.9), d_tgt=0.04, **cfg):
    geo = np.zeros(N_GEO)
    geo[EEF:EEF + 3], geo[OBJ:OBJ + 3], geo[D_TGT_XY] = eef, obj, d_tgt
    return channel_index(layout), geo, params(PhysVLAConfig.paper(**cfg), layout), np.zeros(N_MEM)


def run(fn, a_raw, idx, geo, p, mem, commit=True):
    a_raw = np.asarray(a_raw, dtype=float)
    a_phys = a_raw.copy()
    fn(a_raw, a_phys, idx, geo, p, mem, commit)
    return a_phys


def test_approach_veto_opens_the_gripper_only():
    a = [0.3, -0.2, 0.1, 0.0, 0.0, 0.0, 1.0]
    out = run(approach_veto, a, *ctx())
    assert out[6] == -1.0 and np.array_equal(out[:6], a[:6])
    out = run(approach_veto, [0.1, 0.1, 0.1, -1.0], *ctx(FETCH_4D))  # Fetch: +1 is open
    assert out[3] == 1.0


def test_grasp_guidance_blends_toward_the_waypoint_in_action_units():
    idx, geo, p, mem = ctx(beta=0.5, grasp_offset_m=(0.0, 0.0, 0.05))
    a = np.array([0.2, 0.2, -0.4, 0.1, 0.1, 0.1, 1.0])
    out = run(grasp_guidance, a, idx, geo, p, mem)
    waypoint_units = (np.array([0.02, -0.01, 0.95]) - [0.0, 0.0, 1.0]) / 0.05
    np.testing.assert_allclose(out[:3], 0.5 * waypoint_units + 0.5 * a[:3])
    assert np.array_equal(out[3:], a[3:])


def test_transport_smoothing_biases_z_and_remembers_only_when_committed():
    idx, geo, p, mem = ctx(lift_bias_m=0.02, alpha_transport=0.9)
    a = np.array([1.0, 0.0, 0.0, 0, 0, 0, 1.0])
    first = run(transport_smoothing, a, idx, geo, p, mem, commit=False)
    np.testing.assert_allclose(first[:3], [1.0, 0.0, 0.4])  # EMA starts at the biased action
    assert not mem.any()  # look-ahead: no memory written
    mem[ACTIVE] = 1.0
    mem[EMA:EMA + 3] = [0.0, 0.0, 0.0]
    out = run(transport_smoothing, a, idx, geo, p, mem, commit=True)
    np.testing.assert_allclose(out[:3], [0.1, 0.0, 0.04])
    np.testing.assert_allclose(mem[EMA:EMA + 3], [0.1, 0.0, 0.04])


@pytest.mark.parametrize("d_tgt,ramp", [(0.0, 0.0), (0.04, 0.5), (0.2, 1.0)])
def test_place_deceleration_ramp(d_tgt, ramp):
    a = np.array([0.6, -0.4, 0.2, 0.3, 0, 0, 1.0])
    out = run(place_deceleration, a, *ctx(d_tgt=d_tgt, d_thresh_m=0.08))
    np.testing.assert_allclose(out[:3], ramp * a[:3])
    assert np.array_equal(out[3:], a[3:])


def test_temporal_ema_starts_at_the_action_then_smooths():
    idx, geo, p, mem = ctx(alpha_temporal=0.5)
    assert np.allclose(run(temporal_ema, [1.0, 0, 0, 0, 0, 0, 1], idx, geo, p, mem)[:3], [1, 0, 0])
    assert np.allclose(run(temporal_ema, [0.0, 0, 0, 0, 0, 0, 1], idx, geo, p, mem)[:3], [0.5, 0, 0])


def test_source_key_covers_every_correction_file():
    files = {f.name for f in branch_a.SOURCE_FILES}
    on_disk = {f.name for f in (PKG / "lerobot_physvla/core/corrections").glob("*.py")}
    assert on_disk <= files and {"phase.py", "state.py", "branch_a.py"} <= files
    from lerobot_physvla.core import tick

    assert set(branch_a.SOURCE_FILES) < set(tick.TICK_SOURCE_FILES)
    assert {"tick.py", "blend.py", "dynamics.py"} <= {f.name for f in tick.TICK_SOURCE_FILES}


_PROBE = """
import numpy as np
from lerobot_physvla.core.corrector import Corrector
from lerobot_physvla.core.config import PhysVLAConfig
from lerobot_physvla.core.state import PhysState
st = PhysState.empty(1, 7); st.valid[:] = 1; st.dt[:] = 0.05
st.eef_pos[:] = (0, 0, 1.0); st.obj_pos[:] = (0.02, 0, 0.9); st.obj_rest_z[:] = 0.9; st.target_pos[:] = (0.5, 0, 0.9)
c = Corrector(PhysVLAConfig.paper(mode="phys", cap=1.0), 1)
print(repr(float(c(np.zeros((1, 7)), st)[0, 0])))
"""


def test_place_redirect_steers_the_held_object_over_the_target():
    from lerobot_physvla.core.corrections.base import TGT
    from lerobot_physvla.core.corrections.place_redirect import place_redirect

    idx, geo, p, mem = ctx(place_rule="redirect", place_gain=0.5)
    geo[OBJ:OBJ + 3] = (0.10, 0.02, 0.95)  # the held object, 4.7 cm off the hand on a rim grasp
    geo[TGT:TGT + 3] = (0.12, -0.01, 0.90)
    a = np.array([0.9, 0.9, -0.3, 0.1, 0.2, 0.3, 1.0])
    out = run(place_redirect, a, idx, geo, p, mem)
    # x, y: 0.5 * (target - object) / 0.05 m per unit; z, rotation and gripper are the policy's
    np.testing.assert_allclose(out[:2], 0.5 * np.array([0.02, -0.03]) / 0.05)
    np.testing.assert_array_equal(out[2:], a[2:])


def test_place_redirect_leaves_the_policy_alone_within_its_tolerance_and_steers_only_the_excess():
    from lerobot_physvla.core.corrections.base import TGT
    from lerobot_physvla.core.corrections.place_redirect import place_redirect

    idx, geo, p, mem = ctx(place_rule="redirect", place_gain=0.5, place_tol_m=0.02)
    geo[TGT:TGT + 3] = (0.12, -0.01, 0.90)
    a = np.array([0.3, -0.4, -0.3, 0.1, 0.2, 0.3, 1.0])
    # 1 cm off (a learned policy's own release point): its x, y untouched
    geo[OBJ:OBJ + 3] = (0.12, 0.00, 0.95)
    np.testing.assert_array_equal(run(place_redirect, a, idx, geo, p, mem), a)
    # 5 cm off along y: steered by the 3 cm beyond the tolerance, toward the target
    geo[OBJ:OBJ + 3] = (0.12, 0.04, 0.95)
    out = run(place_redirect, a, idx, geo, p, mem)
    np.testing.assert_allclose(out[:2], [0.0, 0.5 * -0.03 / 0.05], atol=1e-12)
    np.testing.assert_array_equal(out[2:], a[2:])


def test_release_veto_holds_back_only_a_release_that_would_miss_and_yields_after_hold_steps():
    from lerobot_physvla.core.corrections.base import HOLD, TGT
    from lerobot_physvla.core.corrections.release_veto import release_veto

    idx, geo, p, mem = ctx(place_rule="release_veto", place_gain=0.5, place_tol_m=0.02, hold_steps=3)
    geo[TGT:TGT + 3] = (0.12, -0.01, 0.90)
    geo[OBJ:OBJ + 3] = (0.12, 0.04, 0.95)  # 5 cm off the target
    carrying = np.array([0.3, -0.4, -0.3, 0.1, 0.2, 0.3, 1.0])  # gripper closed (robosuite: +1)
    releasing = carrying.copy()
    releasing[6] = -1.0
    # still carrying: every channel the policy's, however far off the object is
    np.testing.assert_array_equal(run(release_veto, carrying, idx, geo, p, mem), carrying)
    assert mem[HOLD] == 0
    # opening 5 cm off: held closed, x, y steered by the 3 cm beyond the tolerance, z the policy's
    out = run(release_veto, releasing, idx, geo, p, mem)
    assert out[6] == 1.0
    np.testing.assert_allclose(out[:2], [0.0, 0.5 * -0.03 / 0.05], atol=1e-12)
    np.testing.assert_array_equal(out[2:6], releasing[2:6])
    # a look-ahead step of a chunk does not advance the hold count
    run(release_veto, releasing, idx, geo, p, mem, commit=False)
    assert mem[HOLD] == 1
    # within the tolerance the release goes through
    geo[OBJ:OBJ + 3] = (0.12, 0.005, 0.95)
    np.testing.assert_array_equal(run(release_veto, releasing, idx, geo, p, mem), releasing)
    assert mem[HOLD] == 0
    # a target out of reach: the hold yields after hold_steps steps in a row
    geo[OBJ:OBJ + 3] = (0.12, 0.04, 0.95)
    held = [run(release_veto, releasing, idx, geo, p, mem)[6] for _ in range(5)]
    assert held == [1.0, 1.0, 1.0, -1.0, -1.0]


def test_release_veto_on_fetch_closes_with_the_layouts_own_sign():
    from lerobot_physvla.core.config import FETCH_4D
    from lerobot_physvla.core.corrections.base import TGT
    from lerobot_physvla.core.corrections.release_veto import release_veto

    idx, geo, p, mem = ctx(layout=FETCH_4D, place_rule="release_veto", place_tol_m=0.02)
    geo[TGT:TGT + 3] = (0.12, -0.01, 0.90)
    geo[OBJ:OBJ + 3] = (0.12, 0.04, 0.95)
    out = run(release_veto, [0.0, 0.0, -0.2, 1.0], idx, geo, p, mem)  # Fetch: +1 = open
    assert out[3] == -1.0


def test_release_carry_holds_the_hand_down_and_steers_to_half_the_tolerance():
    """release_carry: while a release is held back the hand does not rise (the policy's retreat
    would carry the object up and drop it), and a hold under way lets the open through only within
    half of place_tol_m; without it, z is the policy's and the open goes through at the edge."""
    from lerobot_physvla.core.corrections.base import HOLD, TGT
    from lerobot_physvla.core.corrections.release_veto import release_veto

    releasing = np.array([0.3, -0.4, 0.5, 0.1, 0.2, 0.3, -1.0])  # opening while moving up (+z)
    for carry in (False, True):
        idx, geo, p, mem = ctx(place_rule="release_veto", place_tol_m=0.02, release_carry=carry)
        geo[TGT:TGT + 3] = (0.12, -0.01, 0.90)
        geo[OBJ:OBJ + 3] = (0.12, 0.04, 0.95)  # 5 cm off: held back
        out = run(release_veto, releasing, idx, geo, p, mem)
        assert out[6] == 1.0 and out[2] == (0.0 if carry else 0.5)
        down = releasing.copy()
        down[2] = -0.5
        assert run(release_veto, down, idx, geo, p, mem)[2] == -0.5  # lowering stays the policy's
        geo[OBJ:OBJ + 3] = (0.12, 0.005, 0.95)  # 1.5 cm off: inside tol, outside tol / 2
        out = run(release_veto, releasing, idx, geo, p, mem)
        assert out[6] == (1.0 if carry else -1.0)
        geo[OBJ:OBJ + 3] = (0.12, -0.001, 0.95)  # 0.9 cm off: inside tol / 2
        assert run(release_veto, releasing, idx, geo, p, mem)[6] == -1.0 and mem[HOLD] == 0


def test_release_carry_keeps_a_set_down_object_in_place_while_it_is_at_the_hand():
    from lerobot_physvla.core.corrections.release_veto import carried_phase
    from lerobot_physvla.core.corrections.base import CARRIED
    from lerobot_physvla.core.phase import GRASP, PLACE, TRANSPORT

    _, _, p, _ = ctx(place_rule="release_veto", release_carry=True)
    geo, mem = np.zeros(N_GEO), np.zeros(N_MEM)
    geo[EEF:EEF + 3], geo[OBJ:OBJ + 3] = (0.1, 0.0, 1.0), (0.14, 0.0, 0.94)  # a rim grasp: 7 cm off the hand
    assert carried_phase(GRASP, geo, p, mem, True) == GRASP  # never carried to place: eq. 3 as it is
    assert carried_phase(TRANSPORT, geo, p, mem, True) == TRANSPORT and mem[CARRIED] == 0
    assert carried_phase(PLACE, geo, p, mem, True) == PLACE and mem[CARRIED] == 1
    assert carried_phase(GRASP, geo, p, mem, False) == PLACE  # set down at the hand: still placing
    assert carried_phase(GRASP, geo, p, mem, True) == PLACE
    geo[OBJ:OBJ + 3] = (0.1, 0.0, 0.85)  # 15 cm below the hand: let go
    assert carried_phase(GRASP, geo, p, mem, True) == GRASP and mem[CARRIED] == 0
    geo[OBJ:OBJ + 3] = (0.14, 0.0, 0.94)  # back at the hand: a new grasp, not a carried object
    assert carried_phase(GRASP, geo, p, mem, True) == GRASP


def test_release_assist_opens_only_after_a_still_hold_over_a_surface_target_and_stays_open():
    from lerobot_physvla.core.corrections.base import LIFT, STALL, TGT
    from lerobot_physvla.core.corrections.release_assist import release_assist

    idx, geo, p, mem = ctx(place_rule="release_veto", place_tol_m=0.02, release_assist_m=0.04, assist_steps=3)
    geo[TGT:TGT + 3] = (0.12, -0.01, 0.902)  # the plate, at the bowl's resting level
    geo[OBJ:OBJ + 3] = (0.125, -0.005, 0.923)  # the traced failure: held 2 cm above it, on target
    geo[LIFT] = 0.025
    hold = np.array([0.01, 0.0, -0.01, 0.0, 0.0, 0.0, 1.0])  # still, gripper closed (robosuite: +1)
    # a look-ahead step of a chunk neither counts nor opens
    assert run(release_assist, hold, idx, geo, p, mem, commit=False)[6] == 1.0 and mem[STALL] == 0
    outs = [run(release_assist, hold, idx, geo, p, mem)[6] for _ in range(3)]
    assert outs == [1.0, 1.0, -1.0]  # opened on the third still step in a row
    moving = hold.copy()
    moving[2] = 0.5
    assert run(release_assist, moving, idx, geo, p, mem)[6] == -1.0  # latched: stays open
    np.testing.assert_array_equal(run(release_assist, moving, idx, geo, p, mem)[:6], moving[:6])  # arm the policy's


def test_release_assist_judged_by_the_hand_opens_a_hold_whose_command_swings_inside_each_chunk():
    """assist_still=hand (candidate 12): the traced chunked-ACT hold commands z from -0.04 to +0.065 inside
    each 10-step chunk while its hand stays put; by the command the count restarts every chunk and
    never opens, by the hand it opens; a hand that drifts 4 mm restarts it."""
    from lerobot_physvla.core.corrections.base import EEF, LIFT, STALL, TGT
    from lerobot_physvla.core.corrections.release_assist import release_assist

    swing = [-0.04, -0.04, -0.035, -0.03, 0.0, 0.02, 0.023, 0.03, 0.057, 0.065]  # one chunk's z, traced
    outs = {}
    for still in ("action", "hand"):
        idx, geo, p, mem = ctx(place_rule="release_veto", place_tol_m=0.02, release_assist_m=0.04,
                               assist_still=still)  # assist_steps: the default 10
        geo[TGT:TGT + 3] = (0.12, -0.01, 0.902)
        geo[OBJ:OBJ + 3] = (0.129, -0.01, 0.920)  # 0.9 cm off, 1.8 cm above: act_chunk_weak task 1 / 3
        geo[LIFT] = 0.022
        outs[still] = [run(release_assist, [0.01, 0.012, z, 0, 0, 0, 1.0], idx, geo, p, mem)[6] for z in swing * 3]
    assert outs["action"] == [1.0] * 30  # the count restarts at the chunk's last two steps: never opens
    assert outs["hand"][:9] == [1.0] * 9 and outs["hand"][9] == -1.0  # the tenth still step opens
    # a drifting hand: 4 mm from where the hold began restarts the count (and re-anchors there)
    idx, geo, p, mem = ctx(place_rule="release_veto", place_tol_m=0.02, release_assist_m=0.04,
                           assist_still="hand", assist_steps=3)
    geo[TGT:TGT + 3], geo[OBJ:OBJ + 3], geo[LIFT] = (0.12, -0.01, 0.902), (0.129, -0.01, 0.920), 0.022
    hold = [0.0, 0.0, 0.0, 0, 0, 0, 1.0]
    assert run(release_assist, hold, idx, geo, p, mem)[6] == 1.0 and mem[STALL] == 1
    geo[EEF] += 0.004
    assert run(release_assist, hold, idx, geo, p, mem)[6] == 1.0 and mem[STALL] == 0
    assert [run(release_assist, hold, idx, geo, p, mem)[6] for _ in range(3)] == [1.0, 1.0, -1.0]


@pytest.mark.parametrize("case", ["moving", "off_target", "too_high", "target_in_the_air", "already_open"])
def test_release_assist_leaves_every_other_hold_alone(case):
    from lerobot_physvla.core.corrections.base import LIFT, STALL, TGT
    from lerobot_physvla.core.corrections.release_assist import release_assist

    idx, geo, p, mem = ctx(place_rule="release_veto", place_tol_m=0.02, release_assist_m=0.04, assist_steps=3)
    geo[TGT:TGT + 3] = (0.12, -0.01, 0.902)
    geo[OBJ:OBJ + 3] = (0.125, -0.005, 0.923)
    geo[LIFT] = 0.025
    a = np.array([0.01, 0.0, -0.01, 0.0, 0.0, 0.0, 1.0])
    if case == "moving":
        a[1] = -0.2  # still lowering / adjusting: the policy's own place
    elif case == "off_target":
        geo[OBJ] = 0.15  # 3 cm off: the release veto's business, not this one's
    elif case == "too_high":
        geo[OBJ + 2] = 0.96  # 6 cm above the plate
    elif case == "target_in_the_air":  # robosuite Lift: the goal 0.1 m above the cube's rest
        geo[TGT + 2], geo[OBJ + 2], geo[LIFT] = 1.0, 1.0, 0.1
    elif case == "already_open":
        a[6] = -1.0
    outs = [run(release_assist, a, idx, geo, p, mem) for _ in range(6)]
    assert all(np.array_equal(o, a) for o in outs) and mem[STALL] == 0


def _rim_hold(**cfg):
    """The traced single-step ACT hold: the gripper closed on the bowl's rim 4.7 cm off its centre, the
    fingers stopped 13 mm apart, the hand 2.6 cm above the bowl's origin, z command -0.02."""
    from lerobot_physvla.core.corrections.base import FINGERS

    idx, geo, p, mem = ctx(eef=(0.019, -0.047, 0.924), obj=(0.0, 0.0, 0.898), phase_caps=(0.0, 1.0, 0.0, 1.0), beta=0.0,
                           **{"lift_assist_u": 0.5, "assist_steps": 3, **cfg})
    geo[FINGERS] = 0.013
    return idx, geo, p, mem, np.array([0.02, 0.0, -0.02, 0.0, 0.0, 0.0, 1.0])


def test_lift_assist_lifts_a_still_closed_hold_after_assist_steps_and_stops_where_the_hand_rose_alone():
    from lerobot_physvla.core.corrections.base import EEF, LIFT_STALL
    from lerobot_physvla.core.corrections.lift_assist import RISE_M, lift_assist

    idx, geo, p, mem, hold = _rim_hold()
    # a look-ahead step of a chunk neither counts nor lifts
    assert run(lift_assist, hold, idx, geo, p, mem, commit=False)[2] == -0.02 and mem[LIFT_STALL] == 0
    zs = [run(lift_assist, hold, idx, geo, p, mem)[2] for _ in range(3)]
    assert zs == [-0.02, -0.02, 0.5]  # lifted on the third still step in a row
    out = run(lift_assist, hold, idx, geo, p, mem)
    assert out[2] == 0.5 and np.array_equal(np.delete(out, 2), np.delete(hold, 2))  # only z changes
    up = hold.copy()
    up[2] = 0.8
    assert run(lift_assist, up, idx, geo, p, mem)[2] == 0.8  # a policy lifting faster keeps its own command
    geo[EEF + 2] += RISE_M + 0.001  # the hand rose 8 cm and the bowl stayed (the phase is still grasp): stop
    assert run(lift_assist, hold, idx, geo, p, mem)[2] == -0.02 and mem[LIFT_STALL] == -1
    geo[EEF + 2] -= RISE_M + 0.001  # spent for this hold, even back where it began
    assert [run(lift_assist, hold, idx, geo, p, mem)[2] for _ in range(5)] == [-0.02] * 5
    opened = hold.copy()
    opened[6] = -1.0  # the policy opens: a new hold may be lifted again
    run(lift_assist, opened, idx, geo, p, mem)
    assert mem[LIFT_STALL] == 0
    assert [run(lift_assist, hold, idx, geo, p, mem)[2] for _ in range(3)] == [-0.02, -0.02, 0.5]


@pytest.mark.parametrize("case", ["moving", "fingers_on_nothing", "fingers_closing", "commanded_open", "no_gripper"])
def test_lift_assist_leaves_every_other_hold_alone(case):
    from lerobot_physvla.core.corrections.base import EEF, FINGERS, LIFT_STALL
    from lerobot_physvla.core.corrections.lift_assist import lift_assist

    idx, geo, p, mem, a = _rim_hold()
    outs = []
    for k in range(6):
        if case == "moving":
            geo[EEF + 2] = 0.924 + 0.004 * k  # the policy lifts by itself, 4 mm a step
        elif case == "fingers_on_nothing":
            geo[FINGERS] = 0.001  # closed on nothing (act_single_mid T1 / 0): no hold to lift
        elif case == "fingers_closing":
            geo[FINGERS] = 0.08 - 0.012 * k  # still closing: not yet a hold
        elif case == "commanded_open":
            a[6] = -1.0
        elif case == "no_gripper":
            idx = idx.copy()
            idx[3] = -1
        outs.append(run(lift_assist, a, idx, geo, p, mem))
    assert all(np.array_equal(o, a) for o in outs) and mem[LIFT_STALL] <= 2


def test_branch_a_runs_the_lift_assist_in_the_grasp_phase_only_and_forgets_a_hold_outside_it():
    from lerobot_physvla.core.branch_a import branch_a_row
    from lerobot_physvla.core.corrections.base import LIFT_STALL
    from lerobot_physvla.core.phase import GRASP, TRANSPORT

    idx, geo, p, mem, hold = _rim_hold()
    out = np.empty(7)
    for _ in range(3):
        branch_a_row(hold, out, GRASP, idx, geo, p, mem, True)
    assert out[2] == 0.5  # beta 0: the grasp guidance leaves the action; the lift is the only change
    np.testing.assert_array_equal(np.delete(out, 2), np.delete(hold, 2))
    branch_a_row(hold, out, TRANSPORT, idx, geo, p, mem, True)  # lifted past h_lift: the assist ends
    assert mem[LIFT_STALL] == 0
    off = params(PhysVLAConfig.paper(phase_caps=(0.0, 1.0, 0.0, 1.0), beta=0.0), LIBERO_OSC_POSE)  # lift_assist_u 0: off
    mem[:] = 0.0
    for _ in range(5):
        branch_a_row(hold, out, GRASP, idx, geo, off, mem, True)
    np.testing.assert_array_equal(out, hold)


def test_lift_assist_at_rest_leaves_an_object_carried_below_where_it_rested():
    """Candidate 16's traced case (act_chunk, task 9 / 2): the bowl held 4.7 mm, carried 20 cm below its
    rest (eq. 3: grasp), the hand paused: lifted without lift_assist_at_rest, left alone with it; a hold
    at rest is lifted either way."""
    from lerobot_physvla.core.corrections.base import LIFT
    from lerobot_physvla.core.corrections.lift_assist import lift_assist

    for at_rest, below, lifted in ((False, -0.20, True), (True, -0.20, False), (True, 0.0, True), (True, -0.005, True)):
        idx, geo, p, mem, hold = _rim_hold(lift_assist_at_rest=at_rest)
        geo[LIFT] = below
        zs = [run(lift_assist, hold, idx, geo, p, mem)[2] for _ in range(3)]
        assert zs[-1] == (0.5 if lifted else -0.02), (at_rest, below)


def _beside(eef=(0.031, -0.085, 0.968), **cfg):
    """The traced jitter-expert miss: the hand hovering 9 cm from the bowl's origin (its aim error set the
    rim grasp outside the wall), 7 cm above it, the policy open and commanding a small noisy move."""
    idx, geo, p, mem = ctx(eef=eef, obj=(0.0, 0.0, 0.898), phase_caps=(1.0, 1.0, 0.0, 1.0), beta=0.0,
                           **{"rim_guide_m": 0.047, **cfg})
    return idx, geo, p, mem, np.array([0.1, -0.05, -0.3, 0.0, 0.0, 0.0, -1.0])


def _track(geo, mem, steps):
    from lerobot_physvla.core.corrections.rim_guide import rim_track

    for _ in range(steps):
        rim_track(geo, mem)


def test_rim_guide_pulls_a_settled_hand_onto_the_rim_along_its_own_line_only_in_x_y():
    from lerobot_physvla.core.corrections.rim_guide import RIM_ON, RIM_SETTLE_STEPS
    from lerobot_physvla.core.corrections.rim_guide import rim_guide

    idx, geo, p, mem, a = _beside()
    _track(geo, mem, RIM_SETTLE_STEPS - 1)
    np.testing.assert_array_equal(run(rim_guide, a, idx, geo, p, mem), a)  # too few steps seen to call it settled
    _track(geo, mem, 1)
    out = run(rim_guide, a, idx, geo, p, mem)
    rho = np.hypot(0.031, -0.085)
    goal = np.array([0.031, -0.085]) * 0.047 / rho  # the rim point on the hand's own line from the origin
    np.testing.assert_allclose(out[:2], np.clip((goal - [0.031, -0.085]) / 0.05, -1, 1))
    assert out[0] < 0 < out[1]  # inward, toward the bowl
    np.testing.assert_array_equal(out[2:], a[2:])  # z, rotation and the gripper are the policy's
    assert mem[RIM_ON] == 1.0
    geo[EEF:EEF + 2] = [0.02, -0.07]  # moving now (pulled): the pull goes on while the hand is beside and open
    assert run(rim_guide, a, idx, geo, p, mem)[0] != a[0]


@pytest.mark.parametrize("case", ["moving", "closing", "high", "far", "look_ahead"])
def test_rim_guide_leaves_a_hand_that_passes_by_closes_or_is_out_of_the_zone(case):
    from lerobot_physvla.core.corrections.rim_guide import RIM_ON, RIM_SETTLE_STEPS
    from lerobot_physvla.core.corrections.rim_guide import RIM_HEIGHT_FIXED_M, RIM_REACH_FIXED_M, rim_guide

    eef = {"high": (0.031, -0.085, 0.898 + RIM_HEIGHT_FIXED_M + 0.01), "far": (0.0, -RIM_REACH_FIXED_M - 0.01, 0.968)}
    idx, geo, p, mem, a = _beside(**({"eef": eef[case]} if case in eef else {}))
    _track(geo, mem, RIM_SETTLE_STEPS)
    if case == "moving":  # the hand was 2 cm away 5 steps ago: on its way somewhere
        geo[EEF] += 0.02
    if case == "closing":
        a[6] = 1.0
    out = run(rim_guide, a, idx, geo, p, mem, commit=case != "look_ahead")
    if case == "look_ahead":  # a chunk's look-ahead step: corrected, memory untouched
        assert out[0] != a[0] and mem[RIM_ON] == 0.0
        return
    np.testing.assert_array_equal(out, a)
    assert mem[RIM_ON] == 0.0


def test_rim_guide_into_grasp_goes_on_to_the_rim_only_for_a_pull_begun_in_approach():
    """Candidate 19's traced case (act_single_weak, task 3): a hand pulled in to delta_grasp (6 cm) turns the
    phase to grasp; with rim_guide_into_grasp the pull goes on until the hand is within 5 mm of the rim
    point, without it (and for a hand that was not being pulled) the grasp phase leaves x, y alone."""
    from lerobot_physvla.core.branch_a import branch_a_row
    from lerobot_physvla.core.corrections.rim_guide import RIM_ON, RIM_SETTLE_STEPS
    from lerobot_physvla.core.corrections.rim_guide import RIM_ARRIVE_M
    from lerobot_physvla.core.phase import APPROACH, GRASP

    for into, latched in ((True, True), (False, True), (True, False)):
        idx, geo, p, mem, a = _beside(rim_guide_into_grasp=into)
        out = np.empty(7)
        if latched:
            for _ in range(RIM_SETTLE_STEPS + 1):
                branch_a_row(a, out, APPROACH, idx, geo, p, mem, True)
            assert mem[RIM_ON] == 1.0
        geo[EEF:EEF + 2] = [0.0, -0.058]  # inside delta_grasp, 5.8 cm out: the grasp phase
        branch_a_row(a, out, GRASP, idx, geo, p, mem, True)
        if into and latched:
            np.testing.assert_allclose(out[:2], [0.0, (-0.047 + 0.058) / 0.05])  # on toward the rim, along its line
            np.testing.assert_array_equal(out[2:], a[2:])
            assert mem[RIM_ON] == 1.0
        else:
            np.testing.assert_array_equal(out, a)  # beta 0: the grasp phase is the policy's
            assert mem[RIM_ON] == 0.0
    idx, geo, p, mem, a = _beside(rim_guide_into_grasp=True)
    out = np.empty(7)
    for _ in range(RIM_SETTLE_STEPS + 1):
        branch_a_row(a, out, APPROACH, idx, geo, p, mem, True)
    geo[EEF:EEF + 2] = [0.0, -0.047 - RIM_ARRIVE_M + 0.001]  # arrived: the pull ends and stays off
    branch_a_row(a, out, GRASP, idx, geo, p, mem, True)
    np.testing.assert_array_equal(out, a)
    geo[EEF:EEF + 2] = [0.0, -0.058]
    branch_a_row(a, out, GRASP, idx, geo, p, mem, True)
    np.testing.assert_array_equal(out, a)
    assert mem[RIM_ON] == 0.0
    idx, geo, p, mem, a = _beside(rim_guide_into_grasp=True)  # latched again, then the policy closes: it ends
    for _ in range(RIM_SETTLE_STEPS + 1):
        branch_a_row(a, out, APPROACH, idx, geo, p, mem, True)
    geo[EEF:EEF + 2] = [0.0, -0.058]
    a[6] = 1.0
    branch_a_row(a, out, GRASP, idx, geo, p, mem, True)
    np.testing.assert_array_equal(out, a)
    assert mem[RIM_ON] == 0.0


def test_branch_a_runs_the_rim_guide_in_approach_only_leaving_the_gripper_to_the_policy():
    from lerobot_physvla.core.branch_a import branch_a_row
    from lerobot_physvla.core.corrections.rim_guide import RIM_AT, RIM_ON, RIM_SETTLE_STEPS
    from lerobot_physvla.core.phase import APPROACH, GRASP

    idx, geo, p, mem, a = _beside()
    a[6] = 1.0  # closing out here: the paper's approach veto would open it; the rim guide leaves it
    out = np.empty(7)
    for _ in range(RIM_SETTLE_STEPS + 1):
        branch_a_row(a, out, APPROACH, idx, geo, p, mem, True)
    np.testing.assert_array_equal(out, a)  # closing: no pull, and the gripper is the policy's
    assert mem[RIM_AT] == RIM_SETTLE_STEPS + 1  # the hand's track is kept every committed step
    a[6] = -1.0
    branch_a_row(a, out, APPROACH, idx, geo, p, mem, True)
    assert out[0] < 0 < out[1] and mem[RIM_ON] == 1.0
    branch_a_row(a, out, GRASP, idx, geo, p, mem, True)  # inside delta_grasp: the pull ends
    assert mem[RIM_ON] == 0.0
    off = params(PhysVLAConfig.paper(phase_caps=(1.0, 1.0, 0.0, 1.0), beta=0.0), LIBERO_OSC_POSE)  # rim_guide_m 0
    mem[:] = 0.0
    for _ in range(RIM_SETTLE_STEPS + 2):
        branch_a_row(a, out, APPROACH, idx, geo, off, mem, True)
    assert out[6] == LIBERO_OSC_POSE.gripper_open and mem[RIM_AT] == 0  # the paper's veto; nothing tracked


_NEW_CORRECTION = '''"""A test's correction: in the grasp phase, shift x by demo_shift_u action units."""

from numba import njit

from lerobot_physvla.core.corrections import slots
from lerobot_physvla.core.corrections.base import Correction, Field
from lerobot_physvla.core.phase import GRASP

PARAMS = ("DEMO_SHIFT_U",)
MEMORY = (("DEMO_CALLS", 1),)
(DEMO_SHIFT_U,) = slots.params(__file__)
(DEMO_CALLS,) = slots.memory(__file__)


@njit(cache=True, error_model="numpy")
def zz_demo(a_raw, a_phys, idx, geo, p, mem, commit):
    a_phys[idx[0]] += p[DEMO_SHIFT_U]
    if commit:
        mem[DEMO_CALLS] += 1.0


CORRECTION = Correction("zz_demo", GRASP, 9, zz_demo, values={"DEMO_SHIFT_U": lambda c, lay: c.demo_shift_u},
                        on=lambda c: c.demo_shift_u != 0.0,
                        fields=(Field("demo_shift_u", float, 0.0, 0.0, "a shift of x in the grasp phase, action units"),))
'''

_NEW_PROBE = """
import numpy as np, warnings
warnings.simplefilter("ignore")
from lerobot_physvla.core.corrector import Corrector
from lerobot_physvla.core.config import PhysVLAConfig, preset
from lerobot_physvla.flags import build_config, split_argv
from lerobot_physvla.core.state import PhysState
st = PhysState.empty(1, 7); st.valid[:] = 1; st.dt[:] = 0.05
st.eef_pos[:] = (0, 0, 1.0); st.obj_pos[:] = (0.02, 0, 0.9); st.obj_rest_z[:] = 0.9; st.target_pos[:] = (0.5, 0, 0.9)
_, flags, _ = split_argv(["--physvla.preset=paper", "--physvla.mode=phys", "--physvla.cap=1.0", "--physvla.demo_shift_u=0.25"])
on, off = build_config(flags), preset("paper", mode="phys", cap=1.0)
a = np.zeros((1, 7))
print(repr(float(Corrector(on, 1)(a, st)[0, 0] - Corrector(off, 1)(a, st)[0, 0])), PhysVLAConfig().demo_shift_u)
"""


@pytest.mark.slow
def test_a_correction_is_its_file_and_the_cached_kernel_follows_a_new_or_edited_one(tmp_path):
    """A file in core/corrections declaring its slots, its fields and a Correction, and its field's line in the
    PhysVLAConfig class, is all it takes: its field is a PhysVLAConfig field and a --physvla flag, its parameter
    reaches its kernel, and the assembled dispatch calls it in its phase (grasp here), after the paper's grasp
    guidance. Without the class's line, importing the package says which line to add.

    numba's cache checks a kernel against its own file only: an edit to grasp_guidance.py must still reach the
    cached phase_step that compiles it in (closure-keyed, see branch_a.py). One copy of the package, compiled
    cold once (the slow part), serves both."""
    shutil.copytree(PKG / "lerobot_physvla", tmp_path / "lerobot_physvla",
                    ignore=shutil.ignore_patterns("__pycache__"))
    (tmp_path / "lerobot_physvla/core/corrections/zz_demo.py").write_text(_NEW_CORRECTION)
    cache = tmp_path / "numba"
    env = {"PYTHONPATH": str(tmp_path), "PATH": "/usr/bin:/bin", "NUMBA_CACHE_DIR": str(cache)}

    def run(probe):
        return subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True, text=True, cwd=tmp_path)

    r = run(_NEW_PROBE)
    assert r.returncode != 0 and "add `demo_shift_u: float = 0.0` under its group" in r.stderr
    config = tmp_path / "lerobot_physvla/core/config.py"
    text = config.read_text()
    anchor = "    # Branch B (eq. 4-6)\n"  # the corrections' fields come before Branch B's; zz_demo's last of them
    assert text.count(anchor) == 1
    config.write_text(text.replace(anchor, "    demo_shift_u: float = 0.0\n" + anchor))
    r = run(_NEW_PROBE)
    assert r.returncode == 0, r.stderr[-3000:]
    shift, default = r.stdout.strip().splitlines()[-1].split()
    assert float(shift) == pytest.approx(0.25) and float(default) == 0.0
    assert any(cache.rglob("*branch_a*phase_step*.nbi")), "phase_step was not cached"
    assert any(cache.rglob("*tick*correct_tick*.nbi")), "the fused tick was not cached"

    def grasp_probe():
        r = run(_PROBE)
        assert r.returncode == 0, r.stderr
        return float(r.stdout.strip().splitlines()[-1])

    written = {f: f.stat().st_mtime_ns for f in cache.rglob("*")}
    assert grasp_probe() == pytest.approx(0.2)  # grasp phase, beta 0.5: 0.5 * 0.02 m / 0.05 m per unit = 0.2
    assert {f: f.stat().st_mtime_ns for f in cache.rglob("*")} == written  # served from the cache, nothing compiled
    f = tmp_path / "lerobot_physvla/core/corrections/grasp_guidance.py"
    f.write_text(f.read_text().replace("beta, scale = p[BETA], p[METRES_PER_UNIT]",
                                       "beta, scale = 1.0, p[METRES_PER_UNIT]"))
    assert grasp_probe() == pytest.approx(0.4)  # the edit is in effect, not a stale compiled kernel
