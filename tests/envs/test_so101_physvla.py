"""The `so101_physvla` env type: config (from lerobot-env-so101's `so101`), the state-export wrapper around what
`so101` builds (sync vector envs, a picklable factory for async workers), a scripted success counted as lerobot-eval
counts one, the pick-cube task passed through with its reason, and the corrector's layout following action_scale."""

from __future__ import annotations

import pickle
import warnings

import gymnasium as gym
import numpy as np
import pytest

from conftest import make_state
from lerobot.envs.configs import MetaworldEnv
from lerobot_env_so101.configuration_so101 import SO101Env
from lerobot_env_so101.scripted.pick_place import PickPlaceController

from lerobot_physvla.core.config import BEFORE_PULL, ActionLayout, PhysVLAConfig, so101_layout
from lerobot_physvla.core.corrector import Corrector
from lerobot_physvla.core.state import PhysState
from lerobot_physvla.envs.so101_physvla import SO101PhysVLAEnvConfig, SO101StateExport, as_so101_physvla_env
from lerobot_physvla.processor.physvla_processor import EXTRA_KEY, STATE_KEY, PhysVLACorrectorStep
from lerobot_physvla.scripts.lerobot_physvla_eval import for_env

PICK_PLACE = "SO101PickPlace-v0"


def test_so101_config_becomes_so101_physvla_with_the_same_fields_and_the_tasks_features():
    cfg = SO101Env(task=PICK_PLACE, action_scale=0.025, episode_length=40, random_block_position=True)
    out = as_so101_physvla_env(cfg)
    assert isinstance(out, SO101PhysVLAEnvConfig) and out.type == "so101_physvla"
    assert (out.task, out.action_scale, out.episode_length, out.random_block_position, out.fps) == (
        PICK_PLACE, 0.025, 40, True, 10)
    assert out.gym_id == cfg.gym_id == "lerobot_env_so101/SO101PickPlace-v0" and out.horizon == 40
    # the pick-and-place env gives the block and the goal (6); `so101` declares the pick-cube's 3
    assert cfg.features["environment_state"].shape == (3,) and out.features["environment_state"].shape == (6,)
    assert out.features_map == cfg.features_map
    assert SO101PhysVLAEnvConfig(task="SO101PickCube-v0").features["environment_state"].shape == (3,)
    # the pick-and-place env takes no reward_type: `so101`'s gym_kwargs make gym.make raise
    with pytest.raises(TypeError, match="reward_type"):
        gym.make(cfg.gym_id, disable_env_checker=True, **cfg.gym_kwargs)
    assert "reward_type" not in out.gym_kwargs_for(PICK_PLACE) and out.gym_kwargs_for(PICK_PLACE)["action_scale"] == 0.025
    assert as_so101_physvla_env(out) is out and as_so101_physvla_env(MetaworldEnv()).type == "metaworld"


def test_the_corrector_takes_the_so101_layout_at_the_envs_action_scale_unless_a_flag_names_one():
    cfg = PhysVLAConfig()
    out = for_env(cfg, SO101PhysVLAEnvConfig(task=PICK_PLACE, action_scale=0.025))
    lay = out.action_layout
    assert isinstance(lay, ActionLayout) and lay == so101_layout(0.025) and out.weighting == "task_space"
    assert (lay.dim, lay.pos, lay.gripper, lay.metres_per_unit, lay.gripper_open, lay.gripper_shut) == (
        4, (0, 1, 2), 3, 0.025, 1.0, 0.0)
    assert for_env(cfg, SO101PhysVLAEnvConfig(task=PICK_PLACE)).action_layout.metres_per_unit == 1.0  # the default
    # it serialises (policy_postprocessor.json, physvla_diagnostics.json) and comes back the same
    d = out.for_policy(10).to_dict()
    assert d["layout"]["metres_per_unit"] == 0.025 and d["layout"]["gripper_closed"] == 0.0
    assert PhysVLAConfig.from_dict(d) == out.for_policy(10)
    assert PhysVLACorrectorStep(config=d).cfg.action_layout == lay
    given = for_env(cfg.replace(layout="fetch_4d"), SO101PhysVLAEnvConfig(task=PICK_PLACE), given={"layout"})
    assert (given.layout, given.weighting) == ("fetch_4d", "task_space")
    st, raw = make_state(n=5, dt=0.1), np.array([[0.1, 0.0, -0.2, 1.0]])  # the 5-joint SO-101, a 4-D action
    assert np.isfinite(Corrector(out.replace(mode="phys_el"))(raw, st)).all()  # Branch B runs


def test_the_corrector_reads_grasp_zero_as_closed_and_one_as_open():
    """The corrections tell a close from an open by the layout's midpoint (0.5 here), not by the sign. (Without the
    approach pull, which would take the far close of the first case to the block: tests/core/test_approach_pull.py.)"""
    lay = so101_layout(0.025)
    # approach, far from the block: the veto opens a close to 1 (open), never to the symmetric layouts' -1
    st = make_state(n=5, dt=0.1, eef=(0.3, 0.0, 0.2), obj=(0.0, 0.0, 0.02), target=(0.2, 0.1, 0.02))
    c = Corrector(PhysVLAConfig(layout=lay, **BEFORE_PULL))
    np.testing.assert_array_equal(c(np.array([[0.1, 0.0, 0.0, 0.0]]), st), [[0.1, 0.0, 0.0, 1.0]])
    # the veto never opens a gripper that holds (its last command closed, 0): judged on the open-to-closed span
    assert lay.gripper_hold_tol == 0.5 and so101_layout().gripper_hold_tol == 0.5
    c = Corrector(PhysVLAConfig(layout=lay, **BEFORE_PULL))
    at_block = make_state(n=5, dt=0.1, eef=(0.0, 0.0, 0.04), obj=(0.0, 0.0, 0.02), target=(0.2, 0.1, 0.02))
    assert c(np.array([[0.0, 0.0, 0.0, 0.0]]), at_block)[0, 3] == 0.0  # grasp phase: closed on the block
    assert c(np.array([[0.1, 0.0, 0.0, 0.0]]), st)[0, 3] == 0.0  # then far from it: still held, not reopened
    # place, the block lifted 5 cm and 4 cm off the target: an open (0.9) is held back closed (0), a close is left
    st = make_state(n=5, dt=0.1, eef=(0.24, 0.0, 0.09), obj=(0.24, 0.0, 0.07), target=(0.2, 0.0, 0.02), lift=0.05)
    c = Corrector(PhysVLAConfig(layout=lay, **BEFORE_PULL))
    held = c(np.array([[0.0, 0.0, -0.1, 0.9]]), st)
    assert held[0, 3] == 0.0 and held[0, 0] < 0.0  # closed, and steered toward the target
    c.reset()
    np.testing.assert_array_equal(c(np.array([[0.0, 0.0, -0.1, 0.0]]), st), [[0.0, 0.0, -0.1, 0.0]])


def _scripted(vec, controller: PickPlaceController) -> np.ndarray:
    inner = vec.envs[0].unwrapped
    return controller.act(inner.ik_point_pos, inner.data.sensor("block_pos").data, inner.goal_pos)[None]


def test_pick_place_exports_the_sims_state_leaves_the_policys_observation_and_counts_the_success():
    cfg = SO101PhysVLAEnvConfig(task=PICK_PLACE, action_scale=0.025, episode_length=120)
    envs = cfg.create_envs(1)
    assert list(envs) == [PICK_PLACE] and list(envs[PICK_PLACE]) == [0]
    vec = envs[PICK_PLACE][0]
    wrapper = vec.envs[0]
    assert isinstance(wrapper, SO101StateExport) and vec.call("_max_episode_steps") == (120,)
    fn = vec.env_fns[0]  # a plain partial: it pickles into an async worker and builds the same env there
    assert isinstance(pickle.loads(pickle.dumps(fn))(), SO101StateExport)
    with pytest.raises(AttributeError):
        vec.call("task")  # no task string reaches the policy (lerobot-eval would pass one on)
    obs, _ = vec.reset(seed=[0])
    inner = wrapper.unwrapped
    assert set(obs) == {"agent_pos", "environment_state", "robot_state"} and obs["environment_state"].shape == (1, 6)
    controller = PickPlaceController(0.025)
    for t in range(1, 121):
        action = _scripted(vec, controller)
        obs, _, terminated, _, info = vec.step(action)
        st = PhysState.unpack(obs["robot_state"][STATE_KEY])
        extra = obs["robot_state"][EXTRA_KEY][0]
        if terminated[0]:
            break
        own = inner._compute_observation()  # the env's own observation, unchanged
        np.testing.assert_array_equal(obs["agent_pos"][0], own["agent_pos"])
        np.testing.assert_array_equal(obs["environment_state"][0], own["environment_state"])
        assert st.valid[0] == 1 and st.episode_step[0] == t and st.dt[0] == 0.1
        np.testing.assert_array_equal(st.eef_pos[0], inner.ik_point_pos)
        np.testing.assert_array_equal(st.obj_pos[0], inner.data.sensor("block_pos").data)
        np.testing.assert_array_equal(st.target_pos[0], inner.goal_pos)
        np.testing.assert_allclose(extra, np.r_[0, 0, action[0]])  # task 0, not yet a success, the action executed
        assert not info["is_success"][0]
    # the success, as lerobot-eval's rollout reads it (same-step autoreset: the final info)
    assert terminated[0] and t < 120 and info["final_info"]["is_success"][0]
    assert info["final_obs"][0]["robot_state"][EXTRA_KEY][1] == 1.0
    assert PhysState.unpack(obs["robot_state"][STATE_KEY]).episode_step[0] == 0  # the next episode's first row
    vec.close()


def test_the_pick_cube_lift_exports_unsupported_rows_that_pass_through_with_the_reason():
    import lerobot_physvla.envs.so101_physvla as mod
    from lerobot_physvla.envs import state_export

    state_export._WARNED_GOALS.clear()
    cfg = SO101PhysVLAEnvConfig(task="SO101PickCube-v0", episode_length=5)
    vec = cfg.create_envs(2)["SO101PickCube-v0"][0]
    with pytest.warns(RuntimeWarning, match=r"unsupported_goal: SO101PickCube-v0 \(a lift with no place") as caught:
        obs, info = vec.reset(seed=[0, 1])
    assert sum("SO101PickCube-v0" in str(w.message) for w in caught) == 1  # said once, not per env
    assert vec.envs[0].unsupported_goal.startswith("SO101PickCube-v0 (a lift with no place")
    st = PhysState.unpack(obs["robot_state"][STATE_KEY])
    assert (st.valid == -1).all() and obs["environment_state"].shape == (2, 3)  # the policy still sees the block
    corrector = Corrector(PhysVLAConfig(layout=cfg.physvla_defaults["layout"]), batch_size=2)
    raw = np.array([[0.01, -0.02, 0.0, 1.0], [0.0, 0.01, -0.01, 0.0]])
    np.testing.assert_array_equal(corrector(raw, st), raw)
    assert corrector.passthrough_counts == {"unsupported_goal": 2}
    obs, *_ = vec.step(raw)
    assert (PhysState.unpack(obs["robot_state"][STATE_KEY]).episode_step == 1).all()
    vec.close()


def test_a_state_source_that_fails_mid_episode_turns_correction_off_without_stopping_the_env():
    cfg = SO101PhysVLAEnvConfig(task=PICK_PLACE, episode_length=5)
    vec = cfg.create_envs(1)[PICK_PLACE][0]
    vec.reset(seed=[0])
    wrapper = vec.envs[0]

    class Broken:
        def read_packed(self):
            raise RuntimeError("sensor bus timeout")

        def step(self):
            pass

    wrapper.source = Broken()
    with warnings.catch_warnings(record=True):
        warnings.simplefilter("always")
        obs, *_ = vec.step(np.array([[0.0, 0.0, 0.0, 1.0]]))
    st = PhysState.unpack(obs["robot_state"][STATE_KEY])
    assert st.valid[0] == 0 and st.episode_step[0] == 1 and st.dt[0] == 0.1 and wrapper.read_failures == 1
    vec.close()
