"""The corrector on a real arm's joint-target actions, as lerobot-rollout's robot action processor
calls it: (action dict, raw observation) -> corrected action dict."""

from __future__ import annotations

import numpy as np
import pytest

from lerobot.processor import RobotProcessorPipeline
from lerobot.processor.converters import robot_action_observation_to_transition, transition_to_robot_action

from lerobot_physvla.processor.physvla_robot_step import PhysVLARobotActionStep
from lerobot_physvla.arms.model import ArmError, ArmModel
from lerobot_physvla.arms.joint_targets import VIRTUAL, JointTargetAdapter

MOTORS = ("shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll")
EEF_AT_ZERO = ArmModel("so101").eef_at(np.zeros(5))  # (0.391, 0, 0.227) m


def obs(deg=(0, 0, 0, 0, 0), gripper=100.0):
    return {**{f"{m}.pos": float(v) for m, v in zip(MOTORS, deg)}, "gripper.pos": gripper,
            "front": np.zeros((4, 4, 3), np.uint8)}  # a camera frame rides along


def act(deg=(2.0, -1.0, 1.5, 0.5, 0.0), gripper=0.0):
    return {**{f"{m}.pos": float(v) for m, v in zip(MOTORS, deg)}, "gripper.pos": gripper}


def pipeline(step):
    return RobotProcessorPipeline(steps=[step], to_transition=robot_action_observation_to_transition,
                                  to_output=transition_to_robot_action)


def test_a_close_far_from_the_object_is_vetoed_and_the_joints_pass_exactly():
    step = PhysVLARobotActionStep(arm="so101", object_xyz=[0.1, 0.3, 0.0], target_xyz=[0.3, -0.2, 0.0])
    a = act(gripper=0.0)  # close, 0.3 m from the object
    out = pipeline(step)((a, obs()))
    assert out["gripper.pos"] == 100.0  # held open
    assert all(out[f"{m}.pos"] == a[f"{m}.pos"] for m in MOTORS)  # no round trip on untouched keys
    assert not step.passthrough_counts


def test_a_close_at_the_object_passes_untouched():
    obj = EEF_AT_ZERO - np.array([0.0, 0.0, 0.02])  # the object right under the gripper
    step = PhysVLARobotActionStep(arm="so101", object_xyz=obj.tolist(), target_xyz=[0.3, -0.2, 0.0])
    a = act(gripper=0.0)
    assert pipeline(step)((a, obs())) == a


def test_a_cartesian_change_is_mapped_to_the_joints_through_the_jacobian():
    arm = ArmModel("so101")
    ad = JointTargetAdapter(arm, damping=1e-6)
    q = np.deg2rad([5.0, -10.0, 20.0, 10.0, 0.0])
    j = arm.dynamics(q, np.zeros(5))["J_pos"]
    raw = ad.to_virtual(q, 50.0, arm.eef_at(q))
    np.testing.assert_allclose(raw, [0, 0, 0, 0.0], atol=1e-12)  # targets at the current pose: no move
    corrected = raw + np.array([0.002, -0.001, 0.0005, 0.0]) / VIRTUAL.metres_per_unit * np.array([1, 1, 1, 0])
    q_new, g_new = ad.from_virtual(corrected, raw, q, 50.0, j)
    np.testing.assert_allclose(j @ (q_new - q), [0.002, -0.001, 0.0005], atol=1e-8)
    assert g_new is None
    raw[3], corrected = 0.0, raw.copy()
    corrected[3] = -1.0  # open
    assert ad.from_virtual(corrected, raw, q, 50.0, j) == (None, 100.0)


def test_missing_joints_fail_on_the_first_call_before_the_robot_moves():
    step = PhysVLARobotActionStep(arm="so101", object_xyz=[0.1, 0.3, 0.0], target_xyz=[0.3, -0.2, 0.0])
    o = obs()
    del o["wrist_flex.pos"]
    with pytest.raises(ArmError, match=r"reads \['wrist_flex.pos'\]"):
        step(_keys(act(), o))
    a = act()
    del a["elbow_flex.pos"]
    with pytest.raises(ArmError, match=r"corrects \['elbow_flex.pos'\], which the policy's action lacks"):
        pipeline(step)((a, obs()))
    with pytest.raises(ArmError, match="unknown arm 'ur5'"):
        PhysVLARobotActionStep(arm="ur5", object_xyz=[0, 0, 0], target_xyz=[0, 0, 0])


def _keys(action, observation):
    from lerobot.lerobot_types import TransitionKey

    return {TransitionKey.ACTION: action, TransitionKey.OBSERVATION: observation}


def test_after_the_first_call_it_never_raises_and_holds_non_finite_targets():
    step = PhysVLARobotActionStep(arm="so101", object_xyz=[0.1, 0.3, 0.0], target_xyz=[0.3, -0.2, 0.0])
    p = pipeline(step)
    p((act(), obs()))
    bad = act()
    bad["elbow_flex.pos"] = float("nan")
    with pytest.warns(RuntimeWarning, match="held_nonfinite_action"):
        out = p((bad, obs(deg=(0, 0, 12.5, 0, 0))))
    assert out["elbow_flex.pos"] == 12.5 and out["shoulder_pan.pos"] == 2.0
    broken = obs()
    broken["shoulder_lift.pos"] = "not a number"  # a reading that fails mid-episode
    with pytest.warns(RuntimeWarning):
        out = p((act(), broken))
    assert out == act() and step.passthrough_counts["invalid_state"] == 1


def test_its_configuration_round_trips():
    step = PhysVLARobotActionStep(arm="so101", fps=15.0, object_key="object.pos", target_xyz=[0.3, -0.2, 0.0])
    again = PhysVLARobotActionStep(**step.get_config())
    assert again.get_config() == step.get_config() and again.source.dt == pytest.approx(1 / 15)


def test_with_branch_b_and_its_guard_any_reading_gives_finite_targets_and_branch_a_still_acts(monkeypatch):
    """phys_el on the arm: extreme or broken readings never raise and never emit a non-finite target;
    a guard that fails turns Branch B off for the tick (counted) while the gripper veto still acts."""
    from lerobot_physvla.core.config import PhysVLAConfig

    step = PhysVLARobotActionStep(arm="so101", object_xyz=[0.1, 0.3, 0.0], target_xyz=[0.3, -0.2, 0.0],
                                  config=PhysVLAConfig.paper(mode="phys_el", gripper_rule="veto").to_dict())
    p = pipeline(step)
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for deg in ((0, 0, 0, 0, 0), (1e6, -1e6, 3e5, 0, 0), (float("inf"), 0, 0, 0, 0), (float("nan"),) * 5,
                    (179.9, -179.9, 90, -90, 45)):
            out = p((act(), obs(deg=deg)))
            assert all(np.isfinite(out[k]) for k in act()), (deg, out)
        monkeypatch.setattr(step.guard, "check", lambda *a, **k: 1 / 0)
        out = p((act(gripper=0.0), obs()))
    assert step.branch_b_off["guard_error"] == 1 and not step.corrector._b_on
    assert out["gripper.pos"] == 100.0  # the close 0.3 m from the object is still vetoed


def test_a_lost_or_old_pose_from_perception_passes_through_with_its_reason_in_the_summary():
    from lerobot_physvla.core.config import preset

    step = PhysVLARobotActionStep(arm="so101", object_key="block", target_xyz=[0.3, -0.2, 0.0], pose_age_key="age",
                                  config=preset("arm", pose_max_age_steps=2).to_dict())
    p = pipeline(step)
    far = {"block.x": 0.1, "block.y": 0.3, "block.z": 0.0}  # 0.3 m away: a close there is vetoed
    assert p((act(), {**obs(), **far, "age": 2.0}))["gripper.pos"] == 100.0  # within the bound: corrected
    with pytest.warns(RuntimeWarning, match="stale_pose"):
        assert p((act(), {**obs(), **far, "age": 3.0})) == act()  # older than the bound: the policy's
    lost = {"block.x": float("nan"), "block.y": float("nan"), "block.z": float("nan")}
    with pytest.warns(RuntimeWarning, match="missing_pose"):
        assert p((act(), {**obs(), **lost, "age": 0.0})) == act()
    assert step.passed_through == {"stale_pose": 1, "missing_pose": 1}
    assert "passed through: missing_pose 1, stale_pose 1" in step.summary()
