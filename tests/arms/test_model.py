"""Arms: the known models load offline and match MuJoCo's own kinematics; a third arm is one
ArmSpec; every mismatch is a one-line ArmError before anything moves."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from lerobot_physvla.arms.model import ARMS, ArmError, ArmModel, ArmSpec, arm_spec, register_arm

# a third arm, as a user would add one: a 3-joint planar arm with a tip site
THREE_LINK = """
<mujoco>
  <worldbody>
    <body name="l1" pos="0 0 0.1">
      <joint name="j_base" type="hinge" axis="0 0 1"/>
      <geom type="capsule" fromto="0 0 0 0.2 0 0" size="0.02" mass="1"/>
      <body name="l2" pos="0.2 0 0">
        <joint name="j_mid" type="hinge" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0.2 0 0" size="0.02" mass="0.5"/>
        <body name="l3" pos="0.2 0 0">
          <joint name="j_tip" type="hinge" axis="0 1 0"/>
          <geom type="capsule" fromto="0 0 0 0.1 0 0" size="0.02" mass="0.2"/>
          <site name="tip" pos="0.1 0 0"/>
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


@pytest.fixture
def three_link(tmp_path):
    path = tmp_path / "three_link.xml"
    path.write_text(THREE_LINK)
    return ArmSpec(name="three_link", mjcf=str(path), joints=("j_base", "j_mid", "j_tip"),
                   motors=("base", "mid", "tip"), eef_site="tip", unit="deg")


@pytest.mark.parametrize("name", sorted(ARMS))
def test_known_arms_load_offline_and_their_kinematics_match_mujoco(name):
    arm = ArmModel(name)
    rng = np.random.default_rng(0)
    lo, hi = arm.model.jnt_range[[arm.model.joint(j).id for j in arm.spec.joints]].T
    q = rng.uniform(np.where(lo < hi, lo, -1.0), np.where(lo < hi, hi, 1.0))
    dyn = arm.dynamics(q, np.zeros(arm.n_joints))
    d = mujoco.MjData(arm.model)  # MuJoCo's own forward pass at the same q
    d.qpos[arm.oracle.qpos_ids] = q
    mujoco.mj_forward(arm.model, d)
    ref = d.site_xpos[arm.oracle.site_id] if arm.oracle.site_id >= 0 else d.xpos[arm.oracle.body_id]
    np.testing.assert_allclose(dyn["eef_pos"], ref, atol=1e-12)
    np.testing.assert_allclose(dyn["bias"], d.qfrc_bias[arm.oracle.dof_ids], atol=1e-9)  # gravity at rest
    assert np.all(np.linalg.eigvalsh(dyn["M"]) > 0)
    assert dyn["J_pos"].shape == (3, arm.n_joints)


def test_the_jacobian_predicts_the_end_effector_motion(three_link):
    arm = ArmModel(three_link)
    q = np.array([0.3, -0.4, 0.7])
    dq = np.array([1e-6, -2e-6, 1.5e-6])
    j = arm.dynamics(q, np.zeros(3))["J_pos"]
    p0 = arm.dynamics(q, np.zeros(3))["eef_pos"].copy()
    p1 = arm.dynamics(q + dq, np.zeros(3))["eef_pos"]
    np.testing.assert_allclose(p1 - p0, j @ dq, atol=1e-11)


def test_a_third_arm_is_one_spec(three_link):
    register_arm(three_link)
    try:
        assert arm_spec("three_link") is three_link and ArmModel("three_link").n_joints == 3
    finally:
        ARMS.pop("three_link")


def test_an_unknown_arm_names_the_known_ones():
    with pytest.raises(ArmError, match="unknown arm 'ur5'; known: panda, so101"):
        ArmModel("ur5")


def test_joint_names_that_the_model_lacks_are_named(three_link):
    bad = ArmSpec(name="bad", mjcf=three_link.mjcf, joints=("j_base", "elbow", "j_tip"), motors=("a", "b", "c"),
                  eef_site="tip")
    with pytest.raises(ArmError, match=r"joints \['elbow'\] are not in three_link.xml .*j_mid"):
        ArmModel(bad)


def test_a_missing_site_model_or_package_is_one_line(three_link, tmp_path):
    with pytest.raises(ArmError, match="end-effector site 'hand' not in the model"):
        ArmModel(ArmSpec(name="x", mjcf=three_link.mjcf, joints=("j_base",), motors=("a",), eef_site="hand"))
    with pytest.raises(ArmError, match="no arm model at"):
        ArmModel(ArmSpec(name="x", mjcf=str(tmp_path / "none.xml"), joints=("j",), motors=("a",), eef_site="s"))
    with pytest.raises(ArmError, match="needs the package 'no_such_pkg'"):
        ArmModel(ArmSpec(name="x", mjcf="no_such_pkg:arm.xml", joints=("j",), motors=("a",), eef_site="s"))
    with pytest.raises(ArmError, match="2 joints for 1 motors"):
        ArmSpec(name="x", mjcf="m.xml", joints=("a", "b"), motors=("a",), eef_site="s")
