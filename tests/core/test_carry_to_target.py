"""The carry to the target (core/corrections/carry_to_target.py, carry_to_target_place.py): an object the policy
lowers (or lets go of) carry_far_m or farther from the target is carried over it, 15 cm above the target's origin,
through the transport and place phases, and set down there; a lowering near the target, a policy that does not
lower, a pose error that covers the distance, and every preset but the default are left as they were."""

from __future__ import annotations

import sys
import warnings

import numpy as np
import pytest

from lerobot_physvla.core.config import PRESETS, PhysVLAConfig
from lerobot_physvla.core.corrections.carry_to_target import CARRY_HEIGHT_M, SET_LIFT_M
from lerobot_physvla.core.corrector import Corrector
from lerobot_physvla.core.phase import Phase
from lerobot_physvla.core.state import PhysState

SCALE = 0.05  # LIBERO's OSC: metres of hand travel per action unit
REST_Z = 0.9
TARGET = np.array([0.0, 0.0, REST_Z])
GRASP = np.array([0.04, 0.0, 0.02])  # the hand's offset from the held object's origin (a rim grasp), m
# the shipped default without the carry (and without the approach pull, so the carry alone acts), and with it; the
# clearance (carry_clear_m) apart, in its own test
OFF = PRESETS["default"].replace(carry_far_m=0.0, carry_clear_m=0.0, approach_pull_m=0.0)
ON = OFF.replace(carry_far_m=0.10)


def _state(t, eef, obj):
    s = PhysState.empty(1, 7)
    s.valid[:], s.dt[:], s.episode_step[:] = 1.0, 0.05, t
    s.obj_pos[:], s.target_pos[:], s.obj_rest_z[:] = obj, TARGET, REST_Z
    s.eef_pos[:], s.gripper[:] = eef, 0.04
    s.M[:], s.J_pos[:, :, :3] = np.eye(7), np.eye(3)
    return s


def _run(cfg, start_xy, z_cmd=-0.5, steps=120, lift=0.06):
    """A policy holding an object lifted `lift` m, at start_xy (m from the target), that keeps commanding z_cmd and
    +1 cm a step in y with the gripper closed; the object moves with the closed hand down to its rest height, and
    falls there where the hand opens. (actions, phases, object positions)."""
    c = Corrector(cfg, batch_size=1)
    obj = np.array([*start_xy, REST_Z + lift])
    eef = obj + GRASP
    outs, phases, objs = [], [], []
    for t in range(steps):
        a = np.array([[0.0, 0.2, z_cmd, 0, 0, 0, 1.0]])
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            out = c(a, _state(t, eef, obj))[0]
        outs.append(out)
        phases.append(int(c.last.phase[0]))
        objs.append(obj.copy())
        step = out[:3] * SCALE
        eef = eef + step
        if out[6] > 0 and np.linalg.norm(eef - step - obj - GRASP) < 1e-6:  # held: it moves with the hand
            obj = obj + step
            obj[2] = max(obj[2], REST_Z)
            eef = obj + GRASP
        else:  # let go: it falls to its rest
            obj[2] = REST_Z
    return np.array(outs), phases, np.array(objs)


def _off_target(objs):
    return np.linalg.norm(objs[:, :2] - TARGET[:2], axis=1)


def test_an_object_lowered_far_from_the_target_is_carried_over_it_and_set_down_there():
    outs, phases, objs = _run(ON, (0.18, 0.05), lift=0.10)
    assert phases[0] == Phase.TRANSPORT
    assert outs[0][2] > 0 and outs[0][0] < 0 and outs[0][6] == 1.0  # up and toward the target, held closed
    top = objs[:, 2].max() + GRASP[2]
    assert abs(top - (REST_Z + CARRY_HEIGHT_M)) < 0.02  # carried at its height above the target's origin
    assert Phase.PLACE in phases  # carried on in the place phase, the policy still pushing +y
    opened = [k for k, o in enumerate(outs) if o[6] < 0]
    assert opened, "the carried object was never let go"
    k = opened[0]
    assert _off_target(objs)[k] <= ON.place_tol_m  # let go over the target ...
    assert objs[k][2] - REST_Z <= SET_LIFT_M + 1e-9 and all(o[2] < 0 for o in outs[k - 2:k])  # ... lowered to it
    assert all(o[6] == 1.0 for o in outs[:k])  # and never before
    assert _off_target(objs)[-1] <= ON.place_tol_m and objs[-1][2] == REST_Z
    assert all(o[6] == -1.0 for o in outs[k + 1:])  # and held open
    off, _, objs_off = _run(OFF, (0.18, 0.05), lift=0.10)  # uncorrected: set down where it was lowered
    assert _off_target(objs_off)[-1] > 0.15 and objs_off[-1][2] == REST_Z


def test_a_lowering_within_carry_far_m_and_a_policy_that_does_not_lower_are_left_alone():
    for xy, z in (((0.08, 0.0), -0.5), ((0.0, 0.09), -1.0), ((0.2, 0.0), 0.1), ((0.2, 0.1), -0.2)):
        on, *_ = _run(ON, xy, z_cmd=z, steps=40)
        off, *_ = _run(OFF, xy, z_cmd=z, steps=40)
        np.testing.assert_array_equal(on, off)


def test_no_carry_where_the_pose_error_covers_the_distance():
    told = ON.replace(pose_error_m=0.1)
    on, *_ = _run(told, (0.15, 0.0), steps=40)
    off, *_ = _run(OFF.replace(pose_error_m=0.1), (0.15, 0.0), steps=40)
    np.testing.assert_array_equal(on, off)
    carried, *_ = _run(ON.replace(pose_error_m=0.01), (0.15, 0.0), steps=40)
    assert not np.array_equal(carried, off)


def test_on_in_the_default_off_in_the_other_presets_and_in_a_file_saved_before_it_and_checked():
    assert [n for n, p in PRESETS.items() if p.carry_far_m != 0.0] == ["default", "shift"]
    assert PRESETS["default"].carry_far_m == ON.carry_far_m == 0.10 and PRESETS["default"].carry_clear_m == 0.05
    assert PhysVLAConfig.from_dict({"version": 3, "cap": 0.05}).carry_far_m == 0.0
    with pytest.raises(ValueError, match="carry_far_m"):
        PhysVLAConfig(carry_far_m=-0.1)
    with pytest.raises(ValueError, match=r"carry_far_m.*\(1, 1, 1, 1\)"):
        PhysVLAConfig(carry_far_m=0.1, approach_pull_m=0.0, phase_caps=(1.0, 1.0, 0.0, 1.0))  # no transport authority


def test_an_object_from_a_shelf_above_the_target_is_carried_clear_of_it_only_with_carry_clear_m(monkeypatch):
    """The plate 25 cm below the shelf the object was lifted from: the carry's height (15 cm over the plate's origin)
    would set the object back down on the shelf, far from the plate, where the carry ends (LIBERO-Spatial task 9,
    traced in eval/studies/shift_heading.toml). With carry_clear_m = 0.05 it stays 5 cm over the shelf until it is
    over the plate."""
    monkeypatch.setattr(sys.modules[__name__], "TARGET", np.array([0.0, 0.0, REST_Z - 0.25]))
    _, _, low = _run(ON, (0.18, 0.05), lift=0.10, steps=60)
    far = _off_target(low) > ON.place_tol_m
    assert (low[far][:, 2] - REST_Z).min() == 0.0  # set down on the shelf, off the plate
    clear = ON.replace(carry_clear_m=0.05)
    _, _, high = _run(clear, (0.18, 0.05), lift=0.10, steps=60)
    far = _off_target(high) > ON.place_tol_m
    assert (high[far][:, 2] - REST_Z).min() >= 0.05 - 0.01  # held clear of the shelf while off the plate
    assert _off_target(high).min() <= ON.place_tol_m  # and brought over the plate
    with pytest.raises(ValueError, match="carry_clear_m"):
        PhysVLAConfig(carry_clear_m=-0.01)
    assert [n for n, p in PRESETS.items() if p.carry_clear_m != 0.0] == ["default", "shift"]
    assert PhysVLAConfig.from_dict({"version": 8, "cap": 0.05}).carry_clear_m == 0.0
