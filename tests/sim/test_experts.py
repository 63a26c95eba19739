"""The scripted expert: stage machine, and each injectable failure mode acts where it should."""

import numpy as np
import pytest

from lerobot_physvla.core.config import FETCH_4D, LIBERO_OSC_POSE
from lerobot_physvla.sim.experts import ExpertConfig, PickPlaceExpert

OBJ = np.array([0.0, 0.0, 0.90])
TGT = np.array([0.20, 0.10, 0.90])


def rollout(expert: PickPlaceExpert, steps: int = 150, eef0=(0.0, -0.25, 1.15)):
    """Kinematic stand-in for a sim: the end effector moves by the commanded metres; the object
    rides with it from the end of the close stage on. Returns per-step (stage, eef, obj, action)."""
    eef, obj, out = np.array(eef0), OBJ.copy(), []
    held = False
    lay = expert.layout
    for _ in range(steps):
        stage = expert.STAGES[expert.stage]
        a = expert.act(eef, obj, TGT)
        out.append((stage, eef.copy(), obj.copy(), a))
        step = a[list(lay.pos)] * lay.metres_per_unit
        eef = eef + step
        held = held or stage == "lift"
        if held and not (stage in ("release", "done") and expert.cfg.release):
            obj = obj + step
    return out


def test_clean_expert_walks_every_stage_and_releases_at_the_target():
    trace = rollout(PickPlaceExpert())
    stages = [s for s, *_ in trace]
    assert stages.index("descend") < stages.index("close") < stages.index("lift") < stages.index("release")
    _, eef, obj, a = next(t for t in trace if t[0] == "release")
    assert np.linalg.norm((obj - TGT)[:2] - np.array(ExpertConfig().place_offset_m[:2]) + np.array(ExpertConfig().grasp_offset_m[:2])) < 0.02
    assert a[6] == LIBERO_OSC_POSE.gripper_open  # opens at the target


def test_lift_waypoint_is_fixed_when_the_lift_starts():
    """The lift leg ends by reaching its waypoint, not by the stall rule, though the grasped
    object (and so the grasp point) rises with the gripper."""
    expert = PickPlaceExpert()
    trace = rollout(expert)
    lift = [t for t in trace if t[0] == "lift"]
    top = max(float(e[2]) for _, e, _, _ in lift)
    c = expert.cfg
    expected = max(TGT[2] + c.place_offset_m[2], OBJ[2] + c.grasp_offset_m[2]) + c.hover_m
    assert top == pytest.approx(expected, abs=0.02)
    assert len(lift) < PickPlaceExpert.STALL_STEPS


def test_grasp_stage_noise_only_near_the_grasp_point():
    clean = rollout(PickPlaceExpert(cfg=ExpertConfig(seed=3)), 40)
    noisy_exp = PickPlaceExpert(cfg=ExpertConfig(action_noise=0.3, noise_stage="grasp"))
    noisy_exp.reset(seed=3)
    far = np.array([0.0, -0.25, 1.15])  # 25 cm from the object: approach, no noise
    a_far = noisy_exp.act(far, OBJ, TGT)
    ref = PickPlaceExpert()
    ref.reset(seed=3)
    np.testing.assert_allclose(a_far, ref.act(far, OBJ, TGT))
    near = OBJ + np.array(ExpertConfig().grasp_offset_m) + np.array([0.0, 0.0, 0.05])
    noisy_exp.stage = ref.stage = 1  # descend
    assert np.abs(noisy_exp.act(near, OBJ, TGT)[:2] - ref.act(near, OBJ, TGT)[:2]).max() > 1e-6
    assert len(clean) == 40


def test_place_bias_units_is_drawn_within_bounds_and_applied_only_at_place():
    exp = PickPlaceExpert(cfg=ExpertConfig(place_bias_units=1.7))
    sizes = []
    for seed in range(30):
        exp.reset(seed=seed)
        sizes.append(np.linalg.norm(exp.place_bias_units))
    assert 0 <= min(sizes) and max(sizes) <= 1.7 and np.std(sizes) > 0.2
    exp.reset(seed=5)
    ref = PickPlaceExpert()
    ref.reset(seed=5)
    eef = np.array([0.0, -0.25, 1.15])
    np.testing.assert_allclose(exp.act(eef, OBJ, TGT), ref.act(eef, OBJ, TGT))  # approach: no bias
    exp.stage = ref.stage = PickPlaceExpert.STAGES.index("lower")
    above = TGT + np.array([0.0, -0.047, 0.12])
    diff = exp.act(above, OBJ, TGT)[:2] - ref.act(above, OBJ, TGT)[:2]
    bias = exp.place_bias_units[:2]
    assert np.linalg.norm(bias) > 0.05
    np.testing.assert_allclose(diff, np.clip(ref.act(above, OBJ, TGT)[:2] + bias, -1, 1) - ref.act(above, OBJ, TGT)[:2])


def test_hold_instead_of_release_keeps_the_gripper_closed_at_the_target():
    exp = PickPlaceExpert(layout=FETCH_4D, cfg=ExpertConfig(release=False, grasp_offset_m=(0, 0, 0),
                                                           place_offset_m=(0, 0, 0), hover_m=0.05))
    trace = rollout(exp, 120)
    assert "release" in [s for s, *_ in trace]
    assert all(a[3] == -FETCH_4D.gripper_open for s, _, _, a in trace if s == "release")
    _, eef, obj, _ = trace[-1]
    assert np.linalg.norm(obj - TGT) < 0.02  # carried to the goal and held there


def test_bad_noise_stage_is_a_clear_error():
    with pytest.raises(ValueError, match="noise_stage"):
        ExpertConfig(noise_stage="transport")
