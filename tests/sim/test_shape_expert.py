"""The shape-aware scripted expert: its grasp and place rules on synthetic geometry, and its stage machine on a
kinematic stand-in (no LIBERO env)."""

import numpy as np
import pytest

from lerobot_physvla.core.config import LIBERO_OSC_POSE
from lerobot_physvla.sim.shape_expert import (
    Grasp, ShapeExpert, ShapeExpertConfig, box_shape, hand_overlap, plan_for, plan_grasp, plan_place,
    shape_from_points,
)
from lerobot_physvla.sources.geometry import Hand

PANDA = Hand(span_m=0.08, pad_half_width_m=0.008, pad_half_height_m=0.008)


def rotated_box(lx, ly, h, yaw, origin_at="centre"):
    """Corner points of a box lx x ly x h turned by yaw about z, about its origin (centre or bottom)."""
    c = np.array([[sx * lx / 2, sy * ly / 2, sz * h / 2] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    r = np.array([[np.cos(yaw), -np.sin(yaw), 0], [np.sin(yaw), np.cos(yaw), 0], [0, 0, 1]])
    pts = c @ r.T
    if origin_at == "bottom":
        pts[:, 2] += h / 2
    return pts


def test_narrow_box_gets_a_centre_grasp_across_its_narrow_side():
    # a cream-cheese box 8.2 x 4.2 cm, 1.8 cm tall, its long side turned 30 deg from world x
    shape = shape_from_points(rotated_box(0.082, 0.042, 0.018, np.radians(30)))
    assert shape.narrow_m == pytest.approx(0.042, abs=1e-3) and shape.long_m == pytest.approx(0.082, abs=1e-3)
    g = plan_grasp(shape, PANDA)
    assert g.kind == "centre"
    assert np.allclose(g.offset[:2], 0.0, atol=1e-6)
    # the fingers close across the narrow side: perpendicular to the long side (30 deg) -> 120 deg
    assert np.degrees(g.yaw) == pytest.approx(120.0, abs=1.5)
    # a flat box is held just above the table (finger tips clear of it), not below its top
    assert shape.bottom_m + ShapeExpertConfig().table_clear_m - 1e-9 <= g.offset[2] <= shape.top_m


def test_round_can_needs_no_wrist_turn():
    can = box_shape((-0.032, -0.032, -0.038), (0.032, 0.032, 0.038))
    g = plan_grasp(can, PANDA)
    assert g.kind == "centre" and g.yaw is None
    assert g.offset[2] == pytest.approx(0.0, abs=0.02)  # about its middle


def test_wide_bowl_gets_a_rim_grasp():
    bowl = box_shape((-0.054, -0.054, 0.002), (0.054, 0.054, 0.052))  # origin at its bottom
    g = plan_grasp(bowl, PANDA)
    assert g.kind == "rim"
    r = np.hypot(*g.offset[:2])
    assert r == pytest.approx(0.054 - PANDA.pad_half_width_m, abs=1e-3)  # the rim less a pad's half width
    assert g.offset[1] < 0 and g.yaw is None  # the -y side, fingers across the wall (world y), no turn
    assert g.offset[2] == pytest.approx(0.052 - ShapeExpertConfig().rim_depth_m)


def test_tall_bottle_is_held_below_its_top_above_its_middle():
    bottle = box_shape((-0.022, -0.022, 0.0), (0.022, 0.022, 0.158))  # a wine bottle, origin at its bottom
    g = plan_grasp(bottle, PANDA)
    assert g.kind == "centre"
    assert 0.079 < g.offset[2] < 0.158  # the upper body: above the middle, below the top
    assert 0.158 - g.offset[2] <= ShapeExpertConfig().grasp_depth_m + 1e-9  # the palm clears the top


def test_grasp_side_avoids_a_neighbour():
    """A tall box right on the bowl's -y side: the rim grasp goes to another side."""
    bowl = box_shape((-0.054, -0.054, 0.002), (0.054, 0.054, 0.052))
    wall = [((-0.2, -0.25), (0.2, -0.07), 0.30)]
    g = plan_grasp(bowl, PANDA, obstacles=wall, obj_pos=(0.0, 0.0, 0.0))
    assert g.kind == "rim" and g.offset[1] >= 0
    assert hand_overlap(np.array(g.offset[:2]), np.pi / 2 if g.yaw is None else g.yaw, g.offset[2], wall) == 0


def test_place_point_is_over_the_target_centre_just_above_its_top():
    obj = box_shape((-0.032, -0.032, -0.038), (0.032, 0.032, 0.038))
    basket = box_shape((-0.06, -0.06, -0.07), (0.06, 0.06, 0.07))
    off, yaw = plan_place(obj, basket, 0.075, Grasp("centre", (0, 0, 0), None))
    assert off[:2] == pytest.approx((0.0, 0.0), abs=1e-9)
    c = ShapeExpertConfig()
    assert off[2] + obj.bottom_m == pytest.approx(0.075 + c.place_clear_m)  # the object's bottom above the top
    assert yaw is None


def test_elongated_region_turns_an_elongated_object_to_it():
    book = shape_from_points(rotated_box(0.10, 0.03, 0.135, np.radians(40), origin_at="bottom"))
    slot = box_shape((-0.028, -0.062, -0.06), (0.028, 0.062, 0.06))  # long along y: narrow direction x
    plan = plan_for(book, slot, -0.06, PANDA)
    assert plan.grasp.kind == "centre"
    assert plan.place_yaw is not None and np.cos(plan.place_yaw) == pytest.approx(1.0, abs=0.01)


def rollout(expert, plan, steps=250, obj0=(0.0, 0.0, 0.9), tgt=(0.2, 0.15, 0.9), eef0=(-0.1, -0.1, 1.15)):
    """Kinematic stand-in: the end effector moves by the commanded metres, the object rides with it from the lift
    on and falls to the target's support top when released."""
    expert.set_plan(plan)
    eef, obj, tgt = np.array(eef0), np.array(obj0), np.array(tgt)
    held, out = False, []
    for _ in range(steps):
        stage = expert.STAGES[expert.stage]
        a = expert.act(eef, obj, tgt, eef_yaw=np.pi / 2, obj_yaw=0.0, eef_down=np.array([0.0, 0.0, -1.0]))
        out.append((stage, eef.copy(), obj.copy(), a))
        step = a[:3] * LIBERO_OSC_POSE.metres_per_unit
        eef = eef + step
        held = held or stage == "lift"
        if held and stage not in ("release", "done"):
            obj = obj + step
    return out


def test_clean_rollout_places_the_object_over_the_target_and_keeps_actions_in_bounds():
    can = box_shape((-0.032, -0.032, -0.038), (0.032, 0.032, 0.038))
    plate = box_shape((-0.07, -0.07, -0.003), (0.07, 0.07, 0.016))
    plan = plan_for(can, plate, 0.016, PANDA, obj_yaw=0.0)
    trace = rollout(ShapeExpert(), plan)
    stages = [s for s, *_ in trace]
    assert stages.index("descend") < stages.index("close") < stages.index("lift") < stages.index("release")
    _, eef, obj, a = next(t for t in trace if t[0] == "release")
    assert np.linalg.norm(obj[:2] - np.array([0.2, 0.15])) < 0.02
    assert obj[2] + can.bottom_m == pytest.approx(0.9 + 0.016 + ShapeExpertConfig().place_clear_m, abs=0.02)
    assert a[6] == LIBERO_OSC_POSE.gripper_open
    acts = np.array([t[3] for t in trace])
    assert np.all(acts >= -1.0) and np.all(acts <= 1.0)


def test_wrist_turns_to_the_grasp_yaw_before_descending():
    box = shape_from_points(rotated_box(0.082, 0.042, 0.018, 0.0))  # long along x: close across y -> no turn
    plan = plan_for(box, box_shape((-0.06,) * 3, (0.06,) * 3), 0.06, PANDA)
    assert np.degrees(plan.grasp.yaw) == pytest.approx(90.0, abs=1.5)
    ex = ShapeExpert()
    ex.set_plan(plan)
    a = ex.act(np.array([0.0, 0.0, 1.2]), np.zeros(3), np.array([0.3, 0, 0]), eef_yaw=0.5, obj_yaw=0.0)
    assert a[5] > 0  # turns the closing direction from 29 deg towards +90 deg (the shorter way)
    a = ex.act(np.array([0.0, 0.0, 1.2]), np.zeros(3), np.array([0.3, 0, 0]), eef_yaw=2.5, obj_yaw=0.0)
    assert a[5] < 0  # from 143 deg: back towards 90 deg
    assert ex.STAGES[ex.stage] == "hover_obj"


def test_failure_modes_keep_their_config_names_and_draws():
    cfg = ShapeExpertConfig(aim_noise_m=0.01, place_bias_m=0.02, premature_close=1.0, action_noise=0.3,
                            place_bias_units=1.0, seed=5)
    ex = ShapeExpert(cfg=cfg)
    ex.reset(seed=7)
    from lerobot_physvla.sim.experts import ExpertConfig, PickPlaceExpert

    ref = PickPlaceExpert(cfg=ExpertConfig(aim_noise_m=0.01, place_bias_m=0.02, premature_close=1.0,
                                           action_noise=0.3, place_bias_units=1.0, seed=5))
    ref.reset(seed=7)
    assert np.allclose(ex.aim, ref.aim) and np.allclose(ex.place_bias, ref.place_bias)
    assert ex.close_early and np.allclose(ex.place_bias_units, ref.place_bias_units)
    can = box_shape((-0.032, -0.032, -0.038), (0.032, 0.032, 0.038))
    ex.set_plan(plan_for(can, can, 0.038, PANDA))
    # premature close: the gripper closes during the approach, near the object
    a = ex.act(np.array([0.05, 0.0, 1.0]), np.array([0.0, 0.0, 0.9]), np.array([0.3, 0.0, 0.9]))
    assert a[6] == -LIBERO_OSC_POSE.gripper_open
    assert np.all(np.abs(a) <= 1.0)


def test_act_without_a_plan_is_a_clear_error():
    with pytest.raises(RuntimeError, match="no plan"):
        ShapeExpert().act(np.zeros(3), np.zeros(3), np.zeros(3))
