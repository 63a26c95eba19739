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
from lerobot_physvla.sources.robosuite import RobosuiteStateSource, goal_object_and_target


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


def test_state_is_the_simulators_own(libero_task0):
    task, env = libero_task0
    libero_sim.reset_to_init_state(env, task, 0)
    src = RobosuiteStateSource(env.env)
    src.reset()
    for _ in range(3):  # moving, so that one physics substep makes a difference
        env.step(np.array([0.5, 0.3, -0.4, 0, 0, 0, -1.0]))
        src.step()
    inner = env.env
    m, d = inner.sim.model._model, inner.sim.data._data
    st = src.read()  # the live data as robosuite's last substep left it
    bowl, plate = inner.obj_body_id["akita_black_bowl_1"], inner.obj_body_id["plate_1"]
    assert st.valid[0] and st.dt[0] == pytest.approx(0.05) and st.episode_step[0] == 3
    np.testing.assert_array_equal(st.obj_pos[0], d.xpos[bowl])
    np.testing.assert_array_equal(st.target_pos[0], d.xpos[plate])
    np.testing.assert_array_equal(st.eef_pos[0], d.site_xpos[inner.robots[0].eef_site_id])
    assert st.n_joints == 7 and np.linalg.matrix_rank(st.J_pos[0]) == 3
    assert 0.0 <= st.gripper[0] < 0.1  # finger opening, m
    # positions are one 2 ms substep older than q: within a millimetre of the forwarded state
    fwd = copy.copy(d)
    mujoco.mj_forward(m, fwd)
    lag = np.abs(st.eef_pos[0] - fwd.site_xpos[inner.robots[0].eef_site_id]).max()
    assert 0.0 < lag < 1e-3
    # forwarded (as robosuite does before every substep), the compiled read equals the recomputing one
    mujoco.mj_forward(m, d)
    st = src.read()
    for name, value in src.oracle.read(d).items():
        np.testing.assert_allclose(getattr(st, name)[0], value, atol=1e-9, err_msg=name)
    np.testing.assert_allclose(st.eef_pos[0], src.oracle.eef_pos(), atol=1e-12)
    src.reset()
    assert src.read().obj_rest_z[0] == pytest.approx(d.xpos[bowl][2])


def test_a_fixed_target_point_overrides_the_target_body(libero_task0):
    _, env = libero_task0
    src = RobosuiteStateSource(env.env)
    src.reset()
    src.target_xyz = np.array([0.1, -0.2, 1.3])
    np.testing.assert_array_equal(src.read().target_pos[0], [0.1, -0.2, 1.3])
    assert src.read_packed() is not src.read_packed()  # every read is a new array


def test_short_scripted_episode_through_phys_el(libero_task0):
    task, env = libero_task0
    libero_sim.reset_to_init_state(env, task, 0)
    src = RobosuiteStateSource(env.env)
    src.reset()
    corr = Corrector(PhysVLAConfig.paper(mode="phys_el"))
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


def test_a_two_object_goal_follows_its_second_object_once_the_first_is_placed():
    """LIBERO-10 task 0, "put both the alphabet soup and the tomato sauce in the basket": In & In."""
    task = libero_sim.load_task("libero_10", 0)
    env = libero_sim.make_libero_env(task)
    libero_sim.reset_to_init_state(env, task, 0)
    inner = env.env
    src = RobosuiteStateSource(inner)
    src.reset()
    assert [p[1] for p in src.goal] == ["alphabet_soup_1", "tomato_sauce_1"]
    assert src.following == "in(alphabet_soup_1, basket_1_contain_region)"
    soup = src.read().obj_pos[0].copy()
    # the soup put in the basket (by hand): once LIBERO's own predicate holds, the source follows the sauce
    basket = src._pos(inner.sim.data._data, src._refs[0][1]).copy()
    joint = inner.objects_dict["alphabet_soup_1"].joints[-1]
    q = inner.sim.data.get_joint_qpos(joint).copy()
    q[:3] = basket + [0.0, 0.0, 0.05]
    inner.sim.data.set_joint_qpos(joint, q)
    inner.sim.forward()
    for _ in range(30):
        env.step(np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -1.0]))
        src.step()
    assert src.following == "in(tomato_sauce_1, basket_1_contain_region)"
    st = src.read()
    sauce = src._pos(inner.sim.data._data, src._refs[1][0])
    assert st.valid[0] == 1.0 and np.allclose(st.obj_pos[0], sauce) and not np.allclose(st.obj_pos[0], soup)
    assert st.obj_rest_z[0] == pytest.approx(sauce[2])  # the new object's rest, read at the switch
    sauce_extent = src.extent("object")
    assert st.scene[0, 0] == pytest.approx(sauce_extent.radius_m) and st.scene[0, 2] == pytest.approx(sauce_extent.top_m)
    src.reset()  # a new episode from the same scene: judged afresh (the soup is still in: the sauce)
    assert src.following == "in(tomato_sauce_1, basket_1_contain_region)"


def test_the_scene_of_the_spatial_bowl_is_measured_and_gives_the_distances_near_the_constants(libero_task0):
    """The bowl, the plate and the Panda's hand as the source reads them from the model; the distances the scene
    gives (core/geometry.py) within 3 mm of the constants the shipped default was fitted with on this bowl."""
    from lerobot_physvla.core.config import PhysVLAConfig
    from lerobot_physvla.core.corrections import params
    from lerobot_physvla.core.corrections.base import P_SLOTS
    from lerobot_physvla.core.geometry import scene_distances
    from lerobot_physvla.core.state import field_offsets

    task, env = libero_task0
    c = PhysVLAConfig()
    for index in (0, 7):  # the bowl is round: the same in every init state
        libero_sim.reset_to_init_state(env, task, index)
        src = RobosuiteStateSource(env.env)
        src.reset()
        row = src.read_packed()
        scene = src.read().scene[0]
        np.testing.assert_allclose(scene[[0, 2, 3]], (0.0539, 0.0521, 0.0687), atol=1e-3)  # bowl radius, top; plate
        np.testing.assert_allclose(scene[4:], (0.08, 0.008, 0.008))  # the Panda: 8 cm span, 8 mm pads
        p = params(c, c.action_layout)
        pe, veto = np.empty_like(p), np.empty(2)
        dg = scene_distances(row, field_offsets(src.oracle.n_joints)["scene"], p, pe,
                             np.array([c.veto_height_m, c.veto_reach_m]), veto)
        got = (dg, veto[0], veto[1], pe[P_SLOTS["RIM_GUIDE_M"]], pe[P_SLOTS["PLACE_TOL_M"]])
        want = (c.delta_grasp_m, c.veto_height_m, c.veto_reach_m, c.rim_guide_m, c.place_tol_m)
        np.testing.assert_allclose(got, want, atol=0.003)
