"""State of real MetaWorld scenes (metaworld's SawyerXYZEnv, no rendering), the `metaworld` action layout measured
on the simulator, and the tasks the corrector models."""

from __future__ import annotations

import warnings

import mujoco
import numpy as np
import pytest

pytest.importorskip("metaworld")

from lerobot_physvla.core.config import LAYOUTS  # noqa: E402
from lerobot_physvla.core.state import SCENE, field_offsets  # noqa: E402
from lerobot_physvla.sources.metaworld import (  # noqa: E402
    ARM_JOINTS, MODELLED, UNSUPPORTED, MetaworldStateSource, UnsupportedTask, check_task)
from lerobot_physvla.sources.robosuite import UnsupportedGoal  # noqa: E402

LAYOUT = LAYOUTS["metaworld"]


def make_sim(task: str = "pick-place-v3", seed: int = 0):
    """A MetaWorld env as lerobot's MetaworldEnv builds it (MT1, seed 42, train task 0, seeded resets)."""
    import metaworld

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        mt1 = metaworld.MT1(task, seed=42)
        env = mt1.train_classes[task]()
        env.set_task(mt1.train_tasks[0])
    env._freeze_rand_vec, env.seeded_rand_vec = False, True
    return reset(env, seed)


def reset(env, seed: int):
    """A seeded reset, as MetaworldEnv.reset does it (SawyerXYZEnv.reset ignores its seed argument)."""
    env.seed(seed)
    env.reset()
    return env


def expert_obs(env) -> np.ndarray:
    """The 39-D observation metaworld's scripted experts read (current frame twice, then the goal)."""
    cur = env._get_curr_obs_combined_no_goal()
    return np.hstack([cur, cur, env._target_pos])


@pytest.fixture(scope="module")
def pick_place():
    env = make_sim()
    yield env
    env.close()


def test_every_metaworld_task_is_judged_once_and_unmodelled_ones_say_why():
    from lerobot.envs.metaworld import TASK_DESCRIPTIONS

    assert set(MODELLED) | set(UNSUPPORTED) == set(TASK_DESCRIPTIONS) and not set(MODELLED) & set(UNSUPPORTED)
    assert {"pick-place-v3", "bin-picking-v3", "shelf-place-v3"} <= set(MODELLED)
    check_task("metaworld-pick-place-v3")  # lerobot's prefix is accepted
    with pytest.raises(UnsupportedGoal, match=r"unsupported_goal: door-open-v3 \(no grasp-carry-place: a door is "
                                              r"pulled\)") as e:
        check_task("door-open-v3")
    assert isinstance(e.value, UnsupportedTask)
    assert e.value.goal == "door-open-v3 (no grasp-carry-place: a door is pulled)"
    with pytest.raises(UnsupportedTask, match="no-such-task-v3 .not a MetaWorld v3 task"):
        check_task("no-such-task-v3")


def test_the_state_is_the_simulators_own_while_the_expert_carries_the_puck(pick_place):
    from metaworld.policies import SawyerPickPlaceV3Policy

    env = reset(pick_place, 1)  # a goal 16 cm over the table
    src = MetaworldStateSource(env)
    assert src.task == "pick-place-v3"  # found from the env's class
    src.reset()
    expert = SawyerPickPlaceV3Policy()
    for steps in range(1, 151):  # until grasped and lifted 3 cm
        env.step(np.clip(expert.get_action(expert_obs(env)), -1, 1))
        src.step()
        if env._get_pos_objects()[2] > src.obj_rest_z + 0.03:
            break
    m, d = env.model, env.data
    st = src.read()
    assert st.valid[0] == 1 and st.episode_step[0] == steps < 150 and st.pose_age[0] == 0
    assert st.dt[0] == pytest.approx(0.0125) == env.dt  # 5 physics steps of 2.5 ms
    np.testing.assert_array_equal(st.eef_pos[0], env.tcp_center)
    np.testing.assert_array_equal(st.obj_pos[0], env._get_pos_objects()[:3])
    np.testing.assert_array_equal(st.target_pos[0], env._target_pos)
    assert st.obj_pos[0, 2] - st.obj_rest_z[0] > 0.02  # lifted
    q_adr = [m.joint(j).qposadr[0] for j in ARM_JOINTS]
    dofs = [m.joint(j).dofadr[0] for j in ARM_JOINTS]
    np.testing.assert_array_equal(st.q[0], d.qpos[q_adr])
    np.testing.assert_array_equal(st.qdot[0], d.qvel[dofs])
    full = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, full, d.qM)
    np.testing.assert_allclose(st.M[0], full[np.ix_(dofs, dofs)], atol=1e-12)
    np.testing.assert_allclose(st.bias[0], d.qfrc_bias[dofs], atol=1e-12)
    # tau is every joint force but inertia and bias (the weld's, the contacts', the damping): EL holds
    np.testing.assert_allclose(full[dofs] @ d.qacc + st.bias[0], st.tau[0], atol=1e-6)
    assert np.abs(st.tau[0]).max() > 1.0
    # the Jacobian is the tcp's: the mean of the two finger sites' (arm columns)
    jr, jl = np.zeros((3, m.nv)), np.zeros((3, m.nv))
    mujoco.mj_jacSite(m, d, jr, None, m.site("rightEndEffector").id)
    mujoco.mj_jacSite(m, d, jl, None, m.site("leftEndEffector").id)
    np.testing.assert_allclose(st.J_pos[0], (jr + jl)[:, dofs] / 2, atol=1e-12)
    # holding the 4 cm puck: the fingers stopped apart, short of the hand's 7 cm span
    assert 0.005 < st.gripper[0] < 0.05
    scene = dict(zip(SCENE, st.scene[0]))
    assert scene["obj_radius"] == pytest.approx(0.02, abs=1e-3) and scene["obj_top"] == pytest.approx(0.02, abs=1e-3)
    assert np.isnan(scene["target_half_width"])  # the goal is a point in the air: unmeasured
    assert scene["hand_span"] == pytest.approx(0.07)
    assert scene["pad_half_width"] == pytest.approx(0.0153, abs=5e-4) and scene["pad_half_height"] == pytest.approx(
        0.0451, abs=5e-4)
    src.reset()
    assert src.episode_step == 0


def test_gripper_command_plus_one_shuts_the_fingers_and_the_layouts_open_value_opens_them(pick_place):
    env = reset(pick_place, 1)
    src = MetaworldStateSource(env, "pick-place-v3")
    src.reset()
    for command, opening in ((1.0, 0.0), (LAYOUT.gripper_open, 0.07), (1.0, 0.0)):
        for _ in range(40):
            env.step(np.array([0.0, 0.0, 0.0, command]))
        assert src.read().gripper[0] == pytest.approx(opening, abs=2e-3), command
    assert LAYOUT.gripper_open == -1.0 and LAYOUT.gripper == 3


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_metres_per_unit_is_the_tool_centres_travel_per_unit_per_step(pick_place, axis):
    env = reset(pick_place, 0)
    start = env.tcp_center.copy()
    u, steps = 0.5, 20
    a = np.zeros(4)
    a[axis] = u if axis != 2 else -u  # down: the hand starts 15 cm over the table
    for _ in range(steps):
        env.step(a)
    for _ in range(30):  # settle behind the mocap target
        env.step(np.zeros(4))
    moved = (env.tcp_center - start)[axis]
    assert abs(moved) / (steps * u) == pytest.approx(LAYOUT.metres_per_unit, rel=0.05)
    assert np.sign(moved) == np.sign(a[axis])
    assert LAYOUT.pos == (0, 1, 2) and LAYOUT.dim == 4


def test_a_target_that_is_a_body_is_measured(pick_place):
    env = make_sim("bin-picking-v3")
    src = MetaworldStateSource(env)
    src.reset()
    st = src.read()
    np.testing.assert_array_equal(st.target_pos[0], env._target_pos)
    assert st.scene[0, SCENE.index("target_half_width")] == pytest.approx(0.1, abs=0.02)  # the target bin
    env.close()


def test_an_unmodelled_task_is_refused_with_its_reason():
    env = make_sim("door-open-v3")
    with pytest.raises(UnsupportedTask, match="a door is pulled"):
        MetaworldStateSource(env)
    env.close()


def test_a_read_that_fails_is_an_invalid_row_not_an_exception(pick_place):
    src = MetaworldStateSource(pick_place)
    src.reset()
    src.env = None  # the env is gone
    with pytest.warns(RuntimeWarning, match="reading the MetaWorld state failed"):
        row = src.read_packed()
    assert row[field_offsets(7)["valid"]] == 0.0 and not row.any()
