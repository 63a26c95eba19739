"""The approach pull (core/corrections/approach_pull.py): a close commanded approach_pull_m or farther from the object
takes the hand there (rise, cross, descend, close, lift) and carries the object over the target; a close nearer than
that, a pose error of 1 cm or more, and the presets without it (paper, smooth, arm) are left as they were."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from lerobot_physvla.core.config import PRESETS, PhysVLAConfig
from lerobot_physvla.core.corrections.approach_pull import (CARRY_M, CLEAR_M, CLOSE_STEPS, GRASP_H_M, LIFT_STEPS,
                                                             LIFT_U, NEAR_M, STALL_MAX_H_M)
from lerobot_physvla.core.corrector import Corrector
from lerobot_physvla.core.phase import Phase
from lerobot_physvla.core.state import PhysState

SCALE = 0.05  # LIBERO's OSC: metres of hand travel per action unit
REST_Z = 0.9
# the carry acts in the transport phase, which the shipped default gives no authority: the pull's configuration gives
# it full authority there, with the paper's transport smoothing made the identity (no EMA, no lift bias)
ON = PRESETS["shift"]
OFF = ON.replace(approach_pull_m=0.0)
TARGET = (0.3, 0.3, REST_Z)


def _state(t, eef, obj):
    s = PhysState.empty(1, 7)
    s.valid[:], s.dt[:], s.episode_step[:] = 1.0, 0.05, t
    s.obj_pos[:], s.target_pos[:], s.obj_rest_z[:] = obj, TARGET, REST_Z
    s.eef_pos[:], s.gripper[:] = eef, 0.08
    s.M[:], s.J_pos[:, :, :3] = np.eye(7), np.eye(3)
    return s


def _run(cfg, start_xy, steps=140, grip=1.0, follow=True, floor=-1.0, nudged=0.0):
    """A policy that keeps closing (gripper +1) and pushing down where it is, a hand that moves SCALE m per action
    unit (never lower than `floor` m above the object's origin: the fingers resting on it), an object at the origin
    (`nudged` m above its rest height) that moves with a closed hand once the pull lifts it (follow); (actions,
    phases, hand positions relative to the object)."""
    c = Corrector(cfg, batch_size=1)
    eef, obj = np.array([*start_xy, REST_Z]), np.array([0.0, 0.0, REST_Z + nudged])
    outs, phases, hands, objs = [], [], [], []
    for t in range(steps):
        a = np.array([[0.02, 0.0, -0.1, 0, 0, 0, grip]])
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            out = c(a, _state(t, eef, obj))[0]
        outs.append(out)
        phases.append(int(c.last.phase[0]))
        hands.append(eef - obj)
        objs.append(obj.copy())
        held = follow and out[6] > 0 and np.linalg.norm((eef - obj)[:2]) < 0.02 and (out[2] > 0 or obj[2] > REST_Z)
        eef = eef + out[:3] * SCALE
        eef[2] = max(eef[2], obj[2] + floor)
        if held:
            obj = obj + out[:3] * SCALE
    return np.array(outs), phases, np.array(hands), np.array(objs)


def test_a_far_close_takes_the_hand_up_over_the_object_down_closes_and_lifts_it():
    outs, phases, hands, objs = _run(ON, (0.2, 0.0), steps=200)
    assert outs[0][2] > 0 and outs[0][0] == 0 and outs[0][6] == -1.0  # rise first, open, no sideways move low
    top = hands[:, 2].max()
    assert CLEAR_M - 0.02 <= top <= CLEAR_M + 0.02  # it crosses at the travel height
    closed = [k for k, o in enumerate(outs) if o[6] > 0]
    assert closed, "the pulled hand never closed"
    k = closed[0]
    crossing = [j for j in range(k) if 0.05 < hands[j][0] < 0.15]
    assert crossing and all(hands[j][2] > CLEAR_M - 0.03 for j in crossing)
    assert np.linalg.norm(hands[k][:2]) <= NEAR_M and hands[k][2] <= GRASP_H_M + 0.01
    assert all(outs[j][2] == 0 for j in range(k, k + CLOSE_STEPS))  # held still while the fingers close
    assert outs[k + CLOSE_STEPS][2] > 0  # then the lift
    assert Phase.TRANSPORT in phases and Phase.PLACE in phases  # lifted, then carried over the target
    carry = [j for j, ph in enumerate(phases) if ph == Phase.TRANSPORT]
    assert all(outs[j][6] == 1.0 for j in carry)  # held closed while carried
    place = phases.index(Phase.PLACE)
    assert np.linalg.norm(objs[place][:2] - TARGET[:2]) < ON.delta_grasp_m  # the object over the target
    assert abs(objs[place][2] + hands[place][2] - (TARGET[2] + CARRY_M)) < 0.03  # the hand at the carry height
    assert outs[place + 1][2] < 0  # then the pull has let go: the policy's own descent, where the carry held height


def test_a_close_nearer_than_approach_pull_m_is_the_shipped_defaults_business():
    for xy in ((-0.08, 0.0), (0.0, -0.09), (0.03, 0.03)):  # the policy moves +1 mm a step in x: toward, across
        on, *_ = _run(ON, xy, steps=30, follow=False)
        off, *_ = _run(OFF, xy, steps=30, follow=False)
        np.testing.assert_array_equal(on, off)


def test_no_pull_with_a_pose_error_of_a_centimetre_or_more_nor_for_an_open_policy():
    told = ON.replace(pose_error_m=NEAR_M)
    for cfg, grip in ((told, 1.0), (ON, -1.0)):
        pulled, *_ = _run(cfg, (0.2, 0.0), steps=30, grip=grip, follow=False)
        plain, *_ = _run(OFF.replace(pose_error_m=cfg.pose_error_m), (0.2, 0.0), steps=30, grip=grip,
                           follow=False)
        np.testing.assert_array_equal(pulled, plain)


def test_a_stalled_descent_closes_where_it_stalls_only_with_the_option():
    """Fingers resting 3.5 cm over the object's origin: the close waits for 1 cm and never comes (the limit traced in
    docs/decisions/29-approach-pull.md); with approach_pull_stall_steps = 10 the hand closes there after 10 steps
    without coming 2 mm lower, and lifts the object. Stalled above STALL_MAX_H_M it never closes."""
    stuck, *_ = _run(ON, (0.2, 0.0), steps=200, floor=0.035)
    assert not (stuck[:, 6] > 0).any()  # held open to the end
    stall = ON.replace(approach_pull_stall_steps=10)
    outs, phases, hands, _ = _run(stall, (0.2, 0.0), steps=200, floor=0.035)
    closed = [k for k, o in enumerate(outs) if o[6] > 0]
    assert closed, "the stalled hand never closed"
    k = closed[0]
    assert abs(hands[k][2] - 0.035) < 1e-9 and np.linalg.norm(hands[k][:2]) <= 3 * NEAR_M
    landed = next(j for j in range(k) if abs(hands[j][2] - 0.035) < 1e-9)
    assert 10 <= k - landed <= 12  # ten steps without progress, then the close
    assert all(outs[j][2] == 0 for j in range(k, k + CLOSE_STEPS)) and outs[k + CLOSE_STEPS][2] > 0  # close, lift
    assert Phase.TRANSPORT in phases
    high, *_ = _run(stall, (0.2, 0.0), steps=200, floor=STALL_MAX_H_M + 0.01)
    assert not (high[:, 6] > 0).any()
    reach, *_ = _run(stall, (0.2, 0.0), steps=200)  # a hand that reaches 1 cm closes as without the option
    plain, *_ = _run(ON, (0.2, 0.0), steps=200)
    np.testing.assert_array_equal(reach, plain)
    with pytest.raises(ValueError, match="approach_pull_stall_steps"):
        PhysVLAConfig(approach_pull_stall_steps=-1)
    assert all(p.approach_pull_stall_steps == 0 for p in PRESETS.values())
    assert PhysVLAConfig.from_dict({"version": 4, "cap": 0.05}).approach_pull_stall_steps == 0


def _run_taken_back(cfg, near_m, steps=60, floor=0.032, start_m=0.2):
    """A policy that closes start_m from the object (engaging the pull), opens for three steps, and closes again whenever
    the hand is within near_m of the object, always pushing down; fingers resting `floor` m over the object's origin (the pull's close
    never comes). (outputs, the policy's gripper commands, hands relative to the object)."""
    c = Corrector(cfg, batch_size=1)
    eef, obj = np.array([start_m, 0.0, REST_Z + 0.05]), np.array([0.0, 0.0, REST_Z])
    outs, grips, hands = [], [], []
    for t in range(steps):
        grip = 1.0 if t < 3 or (t >= 6 and np.linalg.norm((eef - obj)[:2]) < near_m) else -1.0
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            out = c(np.array([[0.0, 0.0, -0.1, 0, 0, 0, grip]]), _state(t, eef, obj))[0]
        outs.append(out)
        grips.append(grip)
        hands.append(eef - obj)
        eef = eef + out[:3] * SCALE
        eef[2] = max(eef[2], obj[2] + floor)
    return np.array(outs), np.array(grips), np.array(hands)


def test_a_policy_that_takes_its_far_close_back_and_closes_at_the_object_has_the_hand_back_only_with_the_option():
    """docs/decisions/32-shift-default.md's failure: the pulled hand stalls 3.2 cm over the object and the policy's own
    later close there is held open to the end. With approach_pull_handback the pull lets go at that close: the
    policy's descent and close come through. A re-close 10 cm or more away, and a policy that never opens, stay
    pulled as without the option."""
    held, grips, _ = _run_taken_back(ON, near_m=0.02)
    assert (grips[10:] > 0).all() and not (held[:, 6] > 0).any()  # without it: held open to the end
    back, _, hands = _run_taken_back(ON.replace(approach_pull_handback=True), near_m=0.02)
    k = next(t for t in range(3, len(grips)) if grips[t] > 0)  # the policy's second close
    np.testing.assert_array_equal(back[:k], held[:k])  # pulled alike until then
    assert back[k][2] == -0.1 and back[k][0] == 0  # from its close on, the policy's own descent
    assert (back[k:, 6] > 0).any() and back[-1][6] > 0  # and its close: the gripper shuts at the object
    assert np.linalg.norm(hands[k][:2]) < 0.02
    far, grips, hands = _run_taken_back(ON, near_m=0.5, start_m=0.45)  # closes again 10 cm or more away: still pulled
    assert grips[6] > 0 and np.linalg.norm(hands[6][:2]) >= ON.approach_pull_m
    far_on, *_ = _run_taken_back(ON.replace(approach_pull_handback=True), near_m=0.5, start_m=0.45)
    np.testing.assert_array_equal(far_on, far)
    keeps, *_ = _run(ON.replace(approach_pull_handback=True), (0.2, 0.0), steps=200)  # never opens: pulled
    plain, *_ = _run(ON, (0.2, 0.0), steps=200)
    np.testing.assert_array_equal(keeps, plain)
    assert not any(p.approach_pull_handback for p in PRESETS.values())
    assert PhysVLAConfig.from_dict({"version": 5, "cap": 0.05}).approach_pull_handback is False


def test_a_policy_that_opens_near_the_object_has_the_hand_back_with_the_open_handback():
    """approach_pull_open_handback: the policy's open, nearer than approach_pull_m and before the pull's own close,
    ends the pull there (from then on the action is its own); an open 10 cm or more away, and a policy that never
    opens, stay pulled as without it."""
    held, grips, hands = _run_taken_back(ON, near_m=0.02)
    cfg = ON.replace(approach_pull_open_handback=True)
    back, _, back_hands = _run_taken_back(cfg, near_m=0.02)
    k = next(t for t in range(3, len(grips)) if grips[t] < 0 and np.linalg.norm(hands[t][:2]) < ON.approach_pull_m)
    np.testing.assert_array_equal(back[:k], held[:k])  # pulled alike until the policy opens near the object
    assert back[k][2] == -0.1 and back[k][0] == 0 and back[k][6] == -1.0  # from then on, the policy's own action
    assert (back[k:, :2] == 0).all() and np.linalg.norm(back_hands[-1][:2]) > 0.02  # not pulled again: left where
    assert (held[k:, :2] != 0).any()  # the policy took it (without: pulled on over the object)
    far_open = ON.replace(approach_pull_open_handback=True)
    plain, *_ = _run(ON, (0.45, 0.0), steps=12, follow=False)  # never opens: pulled as without it
    keeps, *_ = _run(far_open, (0.45, 0.0), steps=12, follow=False)
    np.testing.assert_array_equal(keeps, plain)
    far, far_grips, far_hands = _run_taken_back(ON, near_m=0.0, start_m=0.45, steps=6)  # opens 30 cm or more away
    assert (far_grips[3:6] < 0).all() and (np.linalg.norm(far_hands[3:6, :2], axis=1) >= ON.approach_pull_m).all()
    far_on, *_ = _run_taken_back(far_open, near_m=0.0, start_m=0.45, steps=6)
    np.testing.assert_array_equal(far_on, far)
    assert not any(p.approach_pull_open_handback for p in PRESETS.values())
    assert PhysVLAConfig.from_dict({"version": 6, "cap": 0.05}).approach_pull_open_handback is False


def test_a_close_on_the_way_to_the_object_is_left_to_the_veto_with_the_heading_option():
    """approach_pull_heading_u = 0.3: a policy that closes 20 cm from the object while it commands the hand toward it
    at 0.3 action units or more is not pulled (the shipped default's outputs, step for step); one that closes while
    it stands still, or moves away, is pulled as without the option. The shipped default has it."""
    heading, without = ON, ON.replace(approach_pull_heading_u=0.0)
    assert heading.approach_pull_heading_u == 0.3

    def run(cfg, vx, steps=8):
        c = Corrector(cfg, batch_size=1)
        eef, obj, outs = np.array([0.2, 0.0, REST_Z + 0.05]), np.array([0.0, 0.0, REST_Z]), []
        for t in range(steps):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                outs.append(c(np.array([[vx, 0.0, -0.1, 0, 0, 0, 1.0]]), _state(t, eef, obj))[0])
            eef = eef + np.array([vx, 0.0, 0.0]) * 0.004  # the hand comes 4 mm a step at full speed: still far
        return np.array(outs)

    toward = run(heading, -0.5)  # toward the object (at -x from the hand) at 0.5 units
    np.testing.assert_array_equal(toward, run(OFF, -0.5))  # as with no pull at all, step for step
    assert (toward[:, 6] < 0).all() and (toward[:, 0] == -0.5).all()  # the veto holds it open; the policy's path
    assert run(without, -0.5)[0][2] > 0  # without the option: pulled (the pull's rise)
    for vx in (0.0, -0.2, 0.5):  # standing, slower than 0.3 units, away: pulled
        np.testing.assert_array_equal(run(heading, vx), run(without, vx))
        assert run(heading, vx)[0][2] > 0  # the pull's rise
    with pytest.raises(ValueError, match="approach_pull_heading_u"):
        PhysVLAConfig(approach_pull_heading_u=-0.1)
    assert [n for n, p in PRESETS.items() if p.approach_pull_heading_u != 0.0] == ["default", "shift"]
    assert PhysVLAConfig.from_dict({"version": 7, "cap": 0.05}).approach_pull_heading_u == 0.0


def test_a_missed_grasp_goes_round_again():
    """Also where the fingers nudged the object a millimetre or a centimetre off its rest, which eq. 3 does not call
    lifted: the pull lifted the empty hand for 167 steps, to 97 cm above the box, on LIBERO-Object's
    cream cheese box (eval/trace_episode.py camera_libero_pro --block original --backbone object_act_camera --task 1
    --seed 30, under the shipped default), before the missed lift was judged as eq. 3 judges a lift."""
    for nudged in (0.0, 0.001, 0.5 * ON.h_lift_m):
        outs, phases, _, _ = _run(ON, (0.2, 0.0), steps=160, follow=False, nudged=nudged)
        assert Phase.TRANSPORT not in phases
        closes = [k for k in range(1, len(outs)) if outs[k][6] > 0 and outs[k - 1][6] < 0]
        assert len(closes) >= 2, nudged  # closed, lifted nothing for LIFT_STEPS, came back down and closed again
        lifting = (outs[:, 2] == LIFT_U) & (outs[:, 6] > 0)
        longest = max(len(run) for run in "".join("1" if x else "0" for x in lifting).split("0"))
        assert 0 < longest <= LIFT_STEPS + 1, (nudged, longest)


def test_on_in_the_default_off_in_the_paper_s_the_arm_s_and_smooth_and_in_a_file_saved_before_it_and_checked():
    assert [n for n, p in PRESETS.items() if p.approach_pull_m != 0.0] == ["default", "shift"]
    # the default (`shift` its former name): the pull's configuration and the carry to the target
    # (tests/core/test_carry_to_target.py); smooth and arm keep the default from before them (BEFORE_PULL)
    assert ON == PRESETS["default"] == PRESETS["shift"]
    assert PRESETS["smooth"].approach_pull_m == PRESETS["arm"].approach_pull_m == PRESETS["paper"].approach_pull_m == 0
    assert ON.approach_pull_heading_u == 0.3 and ON.carry_clear_m == 0.05
    assert ON.approach_pull_m == 0.10 and ON.phase_caps == (1.0, 1.0, 1.0, 1.0)
    assert PhysVLAConfig.from_dict({"version": 1, "cap": 0.05}).approach_pull_m == 0.0
    with pytest.raises(ValueError, match="approach_pull_m"):
        PhysVLAConfig(approach_pull_m=-0.1)
    with pytest.raises(ValueError, match="approach_pull_m"):
        PhysVLAConfig(approach_pull_m=0.1, phase_caps=(1.0, 0.0, 0.0, 1.0))
