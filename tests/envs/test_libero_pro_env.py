"""LIBERO-PRO's suites under the `libero_physvla` env type (envs/libero_pro.py), and lerobot's `libero` untouched."""

from __future__ import annotations

import numpy as np
import pytest

from lerobot_physvla.core.state import PhysState
from lerobot_physvla.envs.libero_physvla import LiberoPhysVLAEnvConfig, as_physvla_env

STATE = "physvla_state"


def test_plain_lerobot_libero_does_not_know_them_and_is_restored_after_ours():
    from lerobot.envs import libero as lerobot_libero
    from lerobot.envs.configs import LiberoEnv

    from lerobot_physvla.sim import libero_pro

    get_suite, env_fns = lerobot_libero._get_suite, lerobot_libero._make_env_fns
    with pytest.raises(ValueError, match="Unknown LIBERO suite 'libero_object_swap'"):
        LiberoEnv(task="libero_object_swap").create_envs(1)  # lerobot's own, as without the plugin
    with pytest.raises(libero_pro.LiberoProError, match="libero_spatial_with_red_box cannot be built here: 'red_box'"):
        LiberoPhysVLAEnvConfig(task="libero_spatial_with_red_box", cameras=False).create_envs(1)
    assert (lerobot_libero._get_suite, lerobot_libero._make_env_fns) == (get_suite, env_fns)


@pytest.mark.slow
def test_state_only_env_is_the_scene_the_harness_runs():
    """The same task and init state through lerobot's env (init_state_id 0, seed 0) and through the study's scene
    (seed 0): the same object and target, the base suite's episode length, the task's BDDL language."""
    from lerobot_physvla.envs.libero_pro import LiberoProEnv
    from lerobot_physvla.sim.scenes import make_scene

    cfg = LiberoPhysVLAEnvConfig(task="libero_object_temp_x0.3", task_ids=[2], cameras=False)
    vec = cfg.create_envs(1)["libero_object_temp_x0.3"][2]
    try:
        obs, _ = vec.reset(seed=[0])
        inner = vec.envs[0].unwrapped
        assert isinstance(inner, LiberoProEnv) and inner._max_episode_steps == 280 and inner._init_states.shape[0] == 50
        st = PhysState.unpack(obs["robot_state"][STATE])
        scene = make_scene("libero_object_temp_x0.3/2")
        scene.reset(0)
        ref = scene.read()
        assert inner.task_description == scene.task.language and st.valid[0] == 1
        np.testing.assert_allclose(st.obj_pos[0], ref.obj_pos[0], atol=1e-6)
        np.testing.assert_allclose(st.target_pos[0], ref.target_pos[0], atol=1e-6)
        np.testing.assert_allclose(obs["environment_state"][0], np.r_[ref.obj_pos[0], ref.target_pos[0]], atol=1e-6)
        scene.env.close()
    finally:
        vec.close()


@pytest.mark.slow
def test_libero_with_cameras_becomes_libero_physvla_and_builds_a_distractor_suite():
    from lerobot.envs.configs import LiberoEnv

    cfg = as_physvla_env(LiberoEnv(task="libero_spatial_with_milk", task_ids=[1], observation_height=64,
                                   observation_width=64))
    vec = cfg.create_envs(1)["libero_spatial_with_milk"][1]
    try:
        obs, _ = vec.reset(seed=[0])
        assert obs["pixels"]["image"].shape == (1, 64, 64, 3) and obs["pixels"]["image"].any()
        assert PhysState.unpack(obs["robot_state"][STATE]).valid[0] == 1
        vec.step(np.zeros((1, 7)))
    finally:
        vec.close()


@pytest.mark.slow
def test_async_workers_register_the_replacement_objects_themselves():
    cfg = LiberoPhysVLAEnvConfig(task="libero_spatial_object", task_ids=[1], cameras=False)
    vec = cfg.create_envs(2, use_async_envs=True)["libero_spatial_object"][1]
    try:
        obs, _ = vec.reset(seed=[0, 1])
        st = PhysState.unpack(obs["robot_state"][STATE])
        assert (st.valid == 1).all() and not np.allclose(st.obj_pos[0], st.obj_pos[1])  # init states 0 and 1
        assert vec.call("_max_episode_steps") == (280, 280)
    finally:
        vec.close()


@pytest.mark.slow
def test_first_init_state_starts_lerobot_s_order_where_a_study_s_block_starts():
    """--env.first_init_state=30: sub-env 0's first episode is init state 30, the scene the harness runs as seed 30
    (the same object), the second 31 (n_envs 1); a negative start is refused."""
    from lerobot_physvla.sim.scenes import make_scene

    cfg = LiberoPhysVLAEnvConfig(task="libero_object", task_ids=[1], cameras=False, first_init_state=30)
    vec = cfg.create_envs(1)["libero_object"][1]
    try:
        for seed in (30, 31):
            obs, _ = vec.reset(seed=[seed])
            scene = make_scene("libero_object/1")
            scene.reset(seed)
            np.testing.assert_allclose(PhysState.unpack(obs["robot_state"][STATE]).obj_pos[0], scene.read().obj_pos[0],
                                       atol=1e-6)
            scene.env.close()
    finally:
        vec.close()
    with pytest.raises(ValueError, match="first_init_state"):
        LiberoPhysVLAEnvConfig(task="libero_object", first_init_state=-1)
