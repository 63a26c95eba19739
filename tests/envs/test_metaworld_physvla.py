"""The `metaworld_physvla` env type: config, the state-export wrapper around lerobot's MetaworldEnv (camera-free,
sync vector envs), a task outside the model, and the corrector's layout following the env."""

from __future__ import annotations

import pickle
import warnings

import numpy as np
import pytest

pytest.importorskip("metaworld")

from conftest import make_state  # noqa: E402
from lerobot.envs.configs import LiberoEnv, MetaworldEnv  # noqa: E402

from lerobot_physvla.core.config import LAYOUTS, PhysVLAConfig  # noqa: E402
from lerobot_physvla.core.corrector import Corrector  # noqa: E402
from lerobot_physvla.core.state import PhysState  # noqa: E402
from lerobot_physvla.envs.metaworld_physvla import (  # noqa: E402
    MetaworldPhysVLAEnvConfig, MetaworldStateExport, as_metaworld_physvla_env)
from lerobot_physvla.processor.physvla_processor import EXTRA_KEY, STATE_KEY  # noqa: E402
from lerobot_physvla.scripts.lerobot_physvla_eval import for_env  # noqa: E402


def test_metaworld_config_becomes_metaworld_physvla_with_the_same_fields():
    cfg = MetaworldEnv(task="pick-place-v3", obs_type="pixels_agent_pos")
    out = as_metaworld_physvla_env(cfg)
    assert isinstance(out, MetaworldPhysVLAEnvConfig) and out.type == "metaworld_physvla"
    assert (out.task, out.obs_type, out.fps, out.cameras) == ("pick-place-v3", "pixels_agent_pos", 80, True)
    assert out.features.keys() == cfg.features.keys() and out.features_map == cfg.features_map
    # lerobot's metaworld ignores episode_length (400) and runs 500 steps: so does this env unless it was given
    assert out.episode_length is None and out.horizon == 500
    assert as_metaworld_physvla_env(cfg, given={"task", "episode_length"}).horizon == 400
    assert as_metaworld_physvla_env(out) is out and as_metaworld_physvla_env(LiberoEnv()).type == "libero"


def test_the_corrector_takes_the_envs_layout_and_weighting_unless_the_flags_name_them():
    cfg = PhysVLAConfig()
    mw = MetaworldPhysVLAEnvConfig(task="pick-place-v3")
    out = for_env(cfg, mw)
    assert out.action_layout == LAYOUTS["metaworld"] and out.weighting == "task_space"
    st, raw = make_state(n=7, dt=0.0125), np.array([[0.5, 0.0, -0.2, -1.0]])  # the 7-joint Sawyer, a 4-D action
    assert np.isfinite(Corrector(out.replace(mode="phys_el"))(raw, st)).all()  # Branch B runs
    with pytest.raises(ValueError, match="joint_diag"):
        Corrector(cfg.replace(mode="phys_el", layout="metaworld"))(raw, st)
    given = for_env(cfg.replace(layout="fetch_4d"), mw, given={"layout": "fetch_4d"})
    assert (given.layout, given.weighting) == ("fetch_4d", "task_space")
    assert for_env(cfg, LiberoEnv()) is cfg and for_env(cfg, None) is cfg


def test_the_close_that_meets_joins_the_shipped_presets_on_metaworld_alone():
    """close_meets_onset, confirmed on MetaWorld's env alone (docs/decisions/28-close-meets.md), is on there under
    the shipped presets unless a flag names it, never under the paper's readings, and on no other env."""
    from lerobot_physvla.core.config import preset
    from lerobot_physvla.scripts.lerobot_physvla_eval import preset_of

    mw = MetaworldPhysVLAEnvConfig(task="shelf-place-v3")
    assert PhysVLAConfig().close_meets_onset is False  # the presets do not change
    for name in ("default", "smooth", "arm"):
        assert for_env(preset(name), mw, preset_name=name).close_meets_onset is True
    assert for_env(preset("paper"), mw, preset_name="paper").close_meets_onset is False
    off = {"close_meets_onset": False}
    assert for_env(preset("default", **off), mw, given=off, preset_name="default").close_meets_onset is False
    assert for_env(PhysVLAConfig(), LiberoEnv(), preset_name="default").close_meets_onset is False
    assert (preset_of({}), preset_of({"mode": "phys"}), preset_of({"preset": "smooth"})) == ("default", "default", "smooth")


def test_state_only_config_drops_cameras_and_adds_the_scene():
    cfg = MetaworldPhysVLAEnvConfig(task="pick-place-v3", cameras=False)
    assert set(cfg.features) == {"action", "agent_pos", "environment_state"}
    assert cfg.features_map == {"action": "action", "agent_pos": "observation.state",
                                "environment_state": "observation.environment_state"}
    with pytest.raises(ValueError, match="episode_length"):
        MetaworldPhysVLAEnvConfig(episode_length=0)


def _expert_action(wrapper) -> np.ndarray:
    inner = wrapper.env.unwrapped
    sim = inner._env
    cur = sim._get_curr_obs_combined_no_goal()
    return np.clip(inner.expert_policy.get_action(np.hstack([cur, cur, sim._target_pos])), -1, 1)


def test_state_only_pick_place_exports_the_sims_state_and_the_terminal_state_of_a_success():
    cfg = MetaworldPhysVLAEnvConfig(task="pick-place-v3", cameras=False, episode_length=150)
    vec = cfg.create_envs(1)["pick-place-v3"][0]
    wrapper = vec.envs[0]
    assert isinstance(wrapper, MetaworldStateExport) and vec.call("_max_episode_steps") == (150,)
    fn = vec.env_fns[0]  # a plain partial: it pickles into an async worker and builds the same env there
    assert isinstance(pickle.loads(pickle.dumps(fn))(), MetaworldStateExport)
    obs, _ = vec.reset(seed=[1])
    sim = wrapper.env.unwrapped._env
    sim.render = None  # camera-free: a render would raise
    assert "pixels" not in obs and obs["agent_pos"].shape == (1, 4)
    for t in range(1, 151):
        obs, _, terminated, _, _ = vec.step(_expert_action(wrapper)[None])
        st = PhysState.unpack(obs["robot_state"][STATE_KEY])
        extra = obs["robot_state"][EXTRA_KEY][0]
        np.testing.assert_array_equal(obs["environment_state"][0], np.r_[st.obj_pos[0], st.target_pos[0]])
        if terminated[0]:
            break
        np.testing.assert_array_equal(st.eef_pos[0], sim.tcp_center)
        np.testing.assert_array_equal(st.obj_pos[0], sim._get_pos_objects()[:3])
    assert terminated[0] and extra[1] == 1.0 and extra[0] == 0  # success, task id 0 in its group
    # the row of the success is the terminal state (not MetaworldEnv's own reset): the puck at the goal, held
    assert st.valid[0] == 1 and st.episode_step[0] == t
    assert np.linalg.norm(st.obj_pos[0] - st.target_pos[0]) <= 0.07 and st.gripper[0] > 0.005
    np.testing.assert_allclose(extra[2:], wrapper._last_action)
    obs, *_ = vec.step(np.zeros((1, 4)))  # the vector env's autoreset: a new episode
    assert PhysState.unpack(obs["robot_state"][STATE_KEY]).episode_step[0] == 0
    vec.close()


def test_a_task_outside_the_model_exports_unsupported_rows_that_pass_through_with_the_reason():
    import lerobot_physvla.envs.metaworld_physvla as mod
    from lerobot_physvla.envs import state_export

    state_export._WARNED_GOALS.clear()
    cfg = MetaworldPhysVLAEnvConfig(task="door-open-v3", cameras=False, episode_length=5)
    vec = cfg.create_envs(2)["door-open-v3"][0]
    with pytest.warns(RuntimeWarning, match=r"unsupported_goal: door-open-v3 \(no grasp-carry-place: a door is "
                                            r"pulled\)") as caught:
        obs, info = vec.reset(seed=[0, 1])
    assert sum("door-open-v3" in str(w.message) for w in caught) == 1  # said once, not per env
    assert vec.envs[0].unsupported_goal == "door-open-v3 (no grasp-carry-place: a door is pulled)"
    rows = obs["robot_state"][STATE_KEY]
    st = PhysState.unpack(rows)
    assert (st.valid == -1).all() and np.isfinite(obs["environment_state"]).all()  # the policy still sees the scene
    corrector = Corrector(PhysVLAConfig(layout="metaworld"), batch_size=2)
    raw = np.array([[0.3, -0.2, 0.1, 1.0], [0.0, 0.5, -0.5, -1.0]])
    np.testing.assert_array_equal(corrector(raw, st), raw)
    assert corrector.passthrough_counts == {"unsupported_goal": 2}
    obs, *_ = vec.step(raw)
    assert (PhysState.unpack(obs["robot_state"][STATE_KEY]).episode_step == 1).all()
    vec.close()


def test_a_state_source_that_fails_mid_episode_turns_correction_off_without_stopping_the_env():
    from lerobot.envs.metaworld import MetaworldEnv as LerobotMetaworldEnv

    wrapper = MetaworldStateExport(LerobotMetaworldEnv("pick-place-v3"), cameras=False)
    wrapper.reset(seed=0)

    class Broken:
        def read_packed(self):
            raise RuntimeError("sensor bus timeout")

        def step(self):
            pass

    wrapper.source = Broken()
    with warnings.catch_warnings(record=True):
        warnings.simplefilter("always")
        obs, *_ = wrapper.step(np.zeros(4))
    st = PhysState.unpack(obs["robot_state"][STATE_KEY])
    assert st.valid[0] == 0 and st.episode_step[0] == 1 and wrapper.read_failures == 1
    assert wrapper.render().shape == (64, 64, 3)  # camera-free: a blank frame
    wrapper.close()
