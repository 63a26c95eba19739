"""The physical state from joint readings: what the corrector reads, from a robot's observation."""

from __future__ import annotations

import numpy as np
import pytest

from lerobot_physvla.core.config import PhysVLAConfig
from lerobot_physvla.core.corrector import Corrector
from lerobot_physvla.core.state import PhysState
from lerobot_physvla.arms.model import ArmError, ArmModel
from lerobot_physvla.sources.joint_state import JointStateSource

MOTORS = ("shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll")


def so101_obs(deg, gripper=50.0, **extra):
    return {**{f"{m}.pos": float(v) for m, v in zip(MOTORS, deg)}, "gripper.pos": gripper, **extra}


def test_so101_readings_in_degrees_give_the_model_state():
    src = JointStateSource("so101", dt=1 / 30, object_xyz=(0.25, 0.0, 0.02), target_xyz=(0.2, 0.15, 0.02))
    deg = np.array([10.0, -20.0, 30.0, 15.0, -5.0])
    st = PhysState.unpack(src.read_packed(so101_obs(deg, gripper=100.0)))
    ref = ArmModel("so101").dynamics(np.deg2rad(deg), np.zeros(5))
    assert st.valid[0] == 1.0 and st.episode_step[0] == 0 and st.dt[0] == pytest.approx(1 / 30)
    np.testing.assert_allclose(st.q[0], np.deg2rad(deg))
    np.testing.assert_allclose(st.eef_pos[0], ref["eef_pos"], atol=1e-12)
    np.testing.assert_allclose(st.M[0], ref["M"], atol=1e-12)
    np.testing.assert_allclose(st.tau[0], st.bias[0])  # no torque sensing: held where it is
    assert st.gripper[0] == pytest.approx(0.06) and st.obj_rest_z[0] == pytest.approx(0.02)
    np.testing.assert_allclose(st.target_pos[0], (0.2, 0.15, 0.02))


def test_velocity_is_the_filtered_finite_difference_of_positions():
    raw = JointStateSource("so101", dt=0.1, object_xyz=(0.2, 0, 0), target_xyz=(0.2, 0.1, 0), velocity_cutoff_hz=None)
    filt = JointStateSource("so101", dt=0.1, object_xyz=(0.2, 0, 0), target_xyz=(0.2, 0.1, 0), velocity_cutoff_hz=1.0)
    for src in (raw, filt):
        src.read_packed(so101_obs(np.zeros(5)))
    v_raw = PhysState.unpack(raw.read_packed(so101_obs(np.full(5, 1.0)))).qdot[0]
    v_filt = PhysState.unpack(filt.read_packed(so101_obs(np.full(5, 1.0)))).qdot[0]
    np.testing.assert_allclose(v_raw, np.deg2rad(1.0) / 0.1)
    alpha = 0.1 / (0.1 + 1 / (2 * np.pi * 1.0))
    np.testing.assert_allclose(v_filt, alpha * np.deg2rad(1.0) / 0.1)
    raw.reset()
    assert PhysState.unpack(raw.read_packed(so101_obs(np.full(5, 9.0)))).qdot[0].tolist() == [0.0] * 5


def test_object_and_target_from_observation_keys():
    src = JointStateSource("so101", dt=0.05, object_key="object.pos", target_key="target.pos")
    obs = so101_obs(np.zeros(5), **{"object.pos": [0.3, 0.0, 0.05], "target.pos": np.array([0.1, 0.2, 0.0])})
    src.check(obs)
    st = PhysState.unpack(src.read_packed(obs))
    np.testing.assert_allclose(st.obj_pos[0], (0.3, 0.0, 0.05))
    np.testing.assert_allclose(st.target_pos[0], (0.1, 0.2, 0.0))
    stems = JointStateSource("so101", dt=0.05, object_key="block", target_xyz=(0, 0, 0))
    obs = so101_obs(np.zeros(5), **{"block.x": 0.3, "block.y": -0.1, "block.z": 0.02})
    stems.check(obs)
    np.testing.assert_allclose(PhysState.unpack(stems.read_packed(obs)).obj_pos[0], (0.3, -0.1, 0.02))
    del obs["block.y"]
    with pytest.raises(ArmError, match=r"reads \['block.y'\]"):
        stems.check(obs)


def test_missing_joints_are_named_before_the_robot_moves():
    src = JointStateSource("so101", dt=0.05, object_xyz=(0, 0, 0), target_xyz=(0, 0, 0))
    obs = so101_obs(np.zeros(5))
    del obs["elbow_flex.pos"]
    with pytest.raises(ArmError, match=r"reads \['elbow_flex.pos'\], which the robot's observation lacks"):
        src.check(obs)
    with pytest.warns(RuntimeWarning, match="correction is off"):
        row = src.read_packed(obs)  # at run time: an invalid row, never an exception
    assert row[0] == 0.0 and src.failures == {"KeyError": 1}


def test_bad_configuration_is_one_line():
    with pytest.raises(ArmError, match="control period"):
        JointStateSource("so101", dt=0.0, object_xyz=(0, 0, 0), target_xyz=(0, 0, 0))
    with pytest.raises(ArmError, match="object's and the target's position"):
        JointStateSource("so101", dt=0.05, object_xyz=(0, 0, 0))


def test_the_corrector_reads_it_and_vetoes_a_close_far_from_the_object():
    """The state feeds the core corrector as it is (5 arm joints, task-space weighting): a gripper
    close commanded far from the object is vetoed by the shipped default."""
    from lerobot_physvla.core.config import PRESETS, ActionLayout

    src = JointStateSource("so101", dt=1 / 30, object_xyz=(0.6, 0.3, 0.0), target_xyz=(0.0, 0.3, 0.0))
    row = src.read_packed(so101_obs(np.zeros(5)))
    lay = ActionLayout(dim=4, pos=(0, 1, 2), gripper=3, metres_per_unit=0.05)
    c = Corrector(PRESETS["default"].replace(layout=lay, weighting="task_space"), 1)
    out = c.correct_packed(np.array([[0.0, 0.0, 0.0, 1.0]]), row[None])
    assert out[0, 3] == lay.gripper_open and not c.passthrough_counts


@pytest.mark.parametrize("cutoff", [None, 5.0])
def test_reading_noise_is_estimated_and_the_velocity_noise_follows_the_filter(cutoff):
    """White reading noise on a smooth motion: the estimate from third differences recovers its std,
    and velocity_noise_rad_s is the std of the velocity estimate the source actually produces."""
    rng = np.random.default_rng(1)
    sigma = 0.05  # deg
    est, qd = [], []
    kw = dict(dt=1 / 30, object_xyz=(0.2, 0, 0), target_xyz=(0.2, 0.1, 0), velocity_cutoff_hz=cutoff)
    src, clean = JointStateSource("so101", **kw), JointStateSource("so101", **kw)
    assert np.isnan(src.reading_noise_rad).all()  # unknown before any reading
    for t in range(600):
        smooth = 20 * np.sin(2 * np.pi * t / 90 + np.arange(5))  # deg
        st = PhysState.unpack(src.read_packed(so101_obs(smooth + rng.normal(0, sigma, 5))))
        ref = PhysState.unpack(clean.read_packed(so101_obs(smooth)))
        if t > 30:
            est.append(np.rad2deg(src.reading_noise_rad))
            qd.append(st.qdot[0] - ref.qdot[0])  # the filter is linear: this is the filtered noise alone
    assert np.median(est) == pytest.approx(sigma, rel=0.15)
    assert np.std(qd) == pytest.approx(np.deg2rad(sigma) * src._qdot_gain, rel=0.1)
    assert np.mean(src.velocity_noise_rad_s) == pytest.approx(np.std(qd), rel=0.2)
    fixed = JointStateSource("so101", dt=1 / 30, object_xyz=(0.2, 0, 0), target_xyz=(0.2, 0.1, 0), reading_noise_deg=0.1)
    np.testing.assert_allclose(fixed.reading_noise_rad, np.deg2rad(0.1))
    with pytest.raises(ArmError, match="reading_noise_deg"):
        JointStateSource("so101", dt=1 / 30, object_xyz=(0.2, 0, 0), target_xyz=(0.2, 0.1, 0), reading_noise_deg=-1.0)


def test_a_non_finite_reading_is_skipped_and_does_not_poison_what_follows():
    src = JointStateSource("so101", dt=1 / 30, object_xyz=(0.2, 0, 0), target_xyz=(0.2, 0.1, 0))
    src.read_packed(so101_obs(np.zeros(5)))
    with pytest.warns(RuntimeWarning, match="reading the arm's state failed"):
        bad = PhysState.unpack(src.read_packed(so101_obs([float("inf"), 0, 0, 0, 0])))
    assert bad.valid[0] == 0.0 and src.failures["ValueError"] == 1
    for t in range(1, 12):  # the readings come back: valid, finite velocities, a finite noise estimate
        st = PhysState.unpack(src.read_packed(so101_obs(np.full(5, 0.5 * t))))
    assert st.valid[0] == 1.0 and np.isfinite(st.pack()).all() and np.isfinite(src.reading_noise_rad).all()
    np.testing.assert_allclose(st.qdot[0], np.deg2rad(0.5 * 30), rtol=0.05)  # 0.5 deg per tick at 30 Hz
