"""State of lerobot-env-so101's SO-101 pick-and-place simulation (no rendering), the so101 action layout measured
on the simulator at the configured action_scale, and the pick-cube task's decision."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from lerobot_env_so101.pick_env import SO101PickCubeGymEnv
from lerobot_env_so101.pick_place_env import SO101PickPlaceGymEnv
from lerobot_env_so101.scripted.pick_place import Phase, PickPlaceController

from lerobot_physvla.core.config import so101_layout
from lerobot_physvla.core.state import SCENE, field_offsets
from lerobot_physvla.sources.robosuite import UnsupportedGoal
from lerobot_physvla.sources.so101 import (ARM_JOINTS, MODELLED, UNSUPPORTED, SO101StateSource, UnsupportedTask,
                                           check_task)

SCRIPTED_SCALE = 0.025  # the package's scripted controller's action_scale


@pytest.fixture(scope="module")
def pick_place():
    env = SO101PickPlaceGymEnv(action_scale=SCRIPTED_SCALE)
    env.reset(seed=0)
    yield env
    env.close()


def block(env) -> np.ndarray:
    return env.data.sensor("block_pos").data.copy()


def test_pick_place_is_modelled_and_the_pick_cube_lift_is_not_with_its_reason():
    assert set(MODELLED) == {"SO101PickPlace-v0"} and set(UNSUPPORTED) == {"SO101PickCube-v0"}
    check_task("lerobot_env_so101/SO101PickPlace-v0")  # the gym id is accepted
    with pytest.raises(UnsupportedGoal, match=r"unsupported_goal: SO101PickCube-v0 \(a lift with no place") as e:
        check_task("SO101PickCube-v0")
    assert isinstance(e.value, UnsupportedTask) and "release assist opens the hand" in e.value.goal
    with pytest.raises(UnsupportedTask, match="not an SO-101 task"):
        check_task("SO101Stack-v0")
    env = SO101PickCubeGymEnv()
    env.reset(seed=0)
    with pytest.raises(UnsupportedTask, match="a lift with no place"):  # found from the env's class
        SO101StateSource(env)
    env.close()


def test_the_state_is_the_simulators_own_while_the_scripted_controller_carries_the_block(pick_place):
    env = pick_place
    env.reset(seed=0)
    src = SO101StateSource(env)
    assert src.task == "SO101PickPlace-v0" and src.dt == 0.1 == env.control_dt
    src.reset()
    ctl = PickPlaceController(SCRIPTED_SCALE)
    for steps in range(1, 80):  # until grasped and lifted 3 cm
        env.step(ctl.act(env.ik_point_pos, block(env), env.goal_pos))
        src.step()
        if block(env)[2] > src.obj_rest_z + 0.03:
            break
    m, d = env.model, env.data
    st = src.read()
    assert st.valid[0] == 1 and st.episode_step[0] == steps < 79 and st.pose_age[0] == 0 and st.dt[0] == 0.1
    assert ctl.phase is Phase.LIFT
    np.testing.assert_array_equal(st.eef_pos[0], env.ik_point_pos)  # the point the action moves
    np.testing.assert_array_equal(st.obj_pos[0], block(env))
    np.testing.assert_array_equal(st.target_pos[0], env.goal_pos)
    assert st.obj_rest_z[0] == pytest.approx(0.02)  # the 4 cm block's centre on the table
    q_adr = [m.joint(j).qposadr[0] for j in ARM_JOINTS]
    dofs = [m.joint(j).dofadr[0] for j in ARM_JOINTS]
    np.testing.assert_array_equal(st.q[0], d.qpos[q_adr])
    np.testing.assert_array_equal(st.qdot[0], d.qvel[dofs])
    full = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, full, d.qM)
    np.testing.assert_allclose(st.M[0], full[np.ix_(dofs, dofs)], atol=1e-12)
    np.testing.assert_allclose(st.bias[0], d.qfrc_bias[dofs], atol=1e-12)
    # tau: the servos' and the damping's torques; with the constraint forces (friction loss, contacts) EL holds
    np.testing.assert_allclose(st.tau[0], (d.qfrc_actuator + d.qfrc_applied + d.qfrc_passive)[dofs], atol=1e-12)
    np.testing.assert_allclose(full[dofs] @ d.qacc + st.bias[0], st.tau[0] + d.qfrc_constraint[dofs], atol=1e-6)
    assert np.abs(st.tau[0]).max() > 0.1
    # the Jacobian is the IK point's: the gripperframe site's carried to the point by the angular part
    jp, jr = np.zeros((3, m.nv)), np.zeros((3, m.nv))
    mujoco.mj_jacSite(m, d, jp, jr, m.site("gripperframe").id)
    r = env.ik_point_pos - d.site_xpos[m.site("gripperframe").id]
    np.testing.assert_allclose(st.J_pos[0], (jp - np.cross(r, jr.T).T)[:, dofs], atol=1e-12)
    # the jaws hold the 4 cm block: the pads stopped apart (each ~4 mm into the block's soft contact)
    assert 0.025 < st.gripper[0] < 0.042
    scene = dict(zip(SCENE, st.scene[0]))
    assert [scene[k] for k in ("obj_radius", "obj_half_width", "obj_top")] == pytest.approx([0.02] * 3)
    assert scene["target_half_width"] == pytest.approx(0.05)  # success: the centre within 3 cm of the goal point
    assert scene["hand_span"] == pytest.approx(0.0908, abs=5e-4)
    assert scene["pad_half_width"] == pytest.approx(0.008, abs=1e-5)  # the fixed pad, box half sizes 8 and 7.2 mm
    assert scene["pad_half_height"] == pytest.approx(0.0072, abs=1e-5)
    src.reset()
    assert src.episode_step == 0


def test_grasp_zero_shuts_the_jaws_and_the_layouts_open_value_opens_them(pick_place):
    env = pick_place
    env.reset(seed=0)
    src = SO101StateSource(env, "SO101PickPlace-v0")
    src.reset()
    lay = so101_layout(SCRIPTED_SCALE)
    for command, opening in ((lay.gripper_shut, 0.0), (lay.gripper_open, 0.0908), (lay.gripper_shut, 0.0)):
        for _ in range(10):
            env.step(np.array([0.0, 0.0, 0.0, command]))
        assert src.read().gripper[0] == pytest.approx(opening, abs=1e-3), command
    # at the env's grasp jaw angle the pads are parallel, 40 mm apart (lerobot-env-so101's own figure)
    d = mujoco.MjData(env.model)
    d.qpos[:] = env.data.qpos
    d.qpos[env.model.joint("gripper").qposadr[0]] = 0.46
    mujoco.mj_kinematics(env.model, d)
    assert src.opening(d) == pytest.approx(0.040, abs=2e-4)
    assert (lay.gripper, lay.gripper_open, lay.gripper_shut, lay.gripper_centre) == (3, 1.0, 0.0, 0.5)
    assert list(lay.closes([0.0, 0.2, 0.5, 0.8, 1.0])) == [True, True, False, False, False]


def _travel(scale: float, axis: int, speed_m: float = 0.004, steps: int = 20):
    """The IK target's and the grasp point's travel per step along `axis` (steady, the last 12 steps), m, under
    a constant action of speed_m / scale units from the middle of the workspace, and the action in units."""
    env = SO101PickPlaceGymEnv(action_scale=scale)
    env.reset(seed=0)
    for _ in range(40):  # to the middle of the workspace, 12 cm over the table, then hold
        err = np.array([0.22, -0.05, 0.12]) - env.ik_point_pos
        env.step(np.r_[np.clip(err / scale, -0.01 / scale, 0.01 / scale), 1.0])
    for _ in range(5):
        env.step(np.array([0.0, 0.0, 0.0, 1.0]))
    u = speed_m / scale
    a = np.array([0.0, 0.0, 0.0, 1.0])
    a[axis] = u
    target0 = env._target_ee_pos.copy()
    points = [env.ik_point_pos.copy()]
    for _ in range(steps):
        env.step(a)
        points.append(env.ik_point_pos.copy())
    target_step = (env._target_ee_pos - target0) / steps
    point_step = np.diff(np.array(points)[:, axis])[-12:].mean()
    env.close()
    return target_step, point_step, u


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_metres_per_unit_is_the_configured_action_scale_as_the_sim_steps_it(axis):
    out = {}
    for scale in (1.0, SCRIPTED_SCALE):  # the env config's default, the package's scripted controller's
        lay = so101_layout(scale)
        target_step, point_step, u = _travel(scale, axis)
        # what an action commands: the IK target of the point moves exactly u * metres_per_unit a step
        expected = np.zeros(3)
        expected[axis] = u * lay.metres_per_unit
        np.testing.assert_allclose(target_step, expected, atol=1e-12)
        out[scale] = point_step / (u * lay.metres_per_unit)
    # the grasp point follows its target at 0.8-1.0 of that speed (the IK's top-down constraint and the servos'
    # lag), the same physical motion at either scale
    assert out[1.0] == pytest.approx(out[SCRIPTED_SCALE], abs=1e-9)
    assert 0.75 < out[1.0] <= 1.02, out


def test_a_read_that_fails_is_an_invalid_row_not_an_exception(pick_place):
    src = SO101StateSource(pick_place)
    src.reset()
    src.env = None  # the env is gone
    with pytest.warns(RuntimeWarning, match="reading the SO-101 state failed"):
        row = src.read_packed()
    assert row[field_offsets(5)["valid"]] == 0.0 and not row.any()
