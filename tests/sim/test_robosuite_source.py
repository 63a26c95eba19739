"""State of a real LIBERO-Spatial scene, read offline, and a short scripted episode through phys_el."""

import copy

import mujoco
import numpy as np
import pytest

from lerobot_physvla.sim import libero_sim
from lerobot_physvla.core.config import PhysVLAConfig
from lerobot_physvla.core.corrector import Corrector
from lerobot_physvla.sim.experts import PickPlaceExpert
from lerobot_physvla.core.phase import Phase
from lerobot_physvla.sim.robosuite_source import RobosuiteStateSource, goal_object_and_target


def test_object_and_target_come_from_the_bddl_goal(libero_task0):
    _, env = libero_task0
    assert goal_object_and_target(env.env) == ("akita_black_bowl_1", "plate_1")
    src = RobosuiteStateSource(env.env)
    assert (src.obj_name, src.target_name) == ("akita_black_bowl_1", "plate_1")


def test_unknown_names_list_what_exists(libero_task0):
    _, env = libero_task0
    with pytest.raises(ValueError, match="plate_1") as e:
        RobosuiteStateSource(env.env, obj_name="red_mug_7")
    assert "red_mug_7" in str(e.value)


def test_state_matches_the_simulator(libero_task0):
    task, env = libero_task0
    libero_sim.reset_to_init_state(env, task, 0)
    src = RobosuiteStateSource(env.env)
    src.reset()
    st = src.read()
    inner = env.env
    d = copy.copy(inner.sim.data._data)  # the source reads the current state, forwarded
    mujoco.mj_forward(inner.sim.model._model, d)
    assert st.valid[0] and st.dt[0] == pytest.approx(0.05) and st.episode_step[0] == 0
    np.testing.assert_allclose(st.obj_pos[0], d.xpos[inner.obj_body_id["akita_black_bowl_1"]], atol=1e-9)
    np.testing.assert_allclose(st.target_pos[0], d.xpos[inner.obj_body_id["plate_1"]], atol=1e-9)
    np.testing.assert_allclose(st.eef_pos[0], d.site_xpos[inner.robots[0].eef_site_id], atol=1e-9)
    assert st.obj_rest_z[0] == pytest.approx(st.obj_pos[0, 2])
    assert st.n_joints == 7 and np.linalg.matrix_rank(st.J_pos[0]) == 3
    assert 0.0 <= st.gripper[0] < 0.1  # finger opening, m


def test_short_scripted_episode_through_phys_el(libero_task0):
    task, env = libero_task0
    libero_sim.reset_to_init_state(env, task, 0)
    src = RobosuiteStateSource(env.env)
    src.reset()
    corr = Corrector(PhysVLAConfig(mode="phys_el"))
    expert = PickPlaceExpert()
    phases, devs = [], []
    for _ in range(45):
        st = src.read()
        raw = expert.act(st.eef_pos[0], st.obj_pos[0], st.target_pos[0])[None]
        out = corr(raw, st)
        assert (np.abs(out) <= 1.0).all() and np.isfinite(out).all()
        env.step(out[0])
        src.step()
        phases.append(int(corr.last.phase[0]))
        devs.append(float(corr.last.deviation[0]))
        assert np.isfinite(corr.last.r_el[0]) and corr.last.r_el[0] > 0
    assert not corr.passthrough_counts
    assert phases[0] == Phase.APPROACH and Phase.GRASP in phases  # the expert reaches the bowl
    assert max(devs) > 0 and max(devs) <= 2 * 0.05 + 1e-12
    assert src.episode_step == 45
