from lerobot.envs.configs import LiberoEnv

from lerobot_physvla.envs.libero_physvla import LiberoPhysVLAEnvConfig, as_physvla_env


def test_libero_config_becomes_libero_physvla_with_the_same_fields():
    cfg = LiberoEnv(task="libero_spatial", task_ids=[3], episode_length=40, observation_height=128)
    out = as_physvla_env(cfg)
    assert isinstance(out, LiberoPhysVLAEnvConfig) and out.type == "libero_physvla"
    assert (out.task, out.task_ids, out.episode_length, out.observation_height, out.cameras) == (
        "libero_spatial", [3], 40, 128, True)
    assert out.features.keys() == cfg.features.keys()
    assert as_physvla_env(out) is out


def test_state_only_config_drops_cameras_and_adds_the_scene():
    cfg = LiberoPhysVLAEnvConfig(task="libero_spatial", cameras=False)
    assert "environment_state" in cfg.features
    assert not any(f.type.name == "VISUAL" for f in cfg.features.values())


class _FakeLibero:
    """Just enough of lerobot's LiberoEnv for the state-export wrapper."""

    def __init__(self):
        import gymnasium as gym
        import numpy as np
        from gymnasium import spaces

        class Env(gym.Env):
            task_id = 3
            observation_space = spaces.Dict({"robot_state": spaces.Dict({})})
            action_space = spaces.Box(-1, 1, (7,))

            def reset(self, **kw):
                return {"robot_state": {}}, {}

            def step(self, action):
                return {"robot_state": {}}, 0.0, False, False, {"is_success": False}

        self.env = Env()
        self.np = np


class _FlakySource:
    def __init__(self, good_row, fail_from: int):
        self.row, self.fail_from, self.calls = good_row, fail_from, 0

    def read_packed(self):
        self.calls += 1
        if self.calls >= self.fail_from:
            raise RuntimeError("sensor bus timeout")
        return self.row

    def step(self):
        pass


def test_a_state_source_that_fails_mid_episode_turns_correction_off_without_stopping_the_env():
    import warnings

    import numpy as np
    import pytest

    from lerobot_physvla.core.state import field_offsets, packed_size
    from lerobot_physvla.envs.libero_physvla import PhysVLAStateExport
    from lerobot_physvla.processor.physvla_processor import STATE_KEY

    wrapper = PhysVLAStateExport(_FakeLibero().env, cameras=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        wrapper.reset()
    good = np.ones(packed_size(7))
    wrapper.source = _FlakySource(good, fail_from=2)
    obs, *_ = wrapper.step(np.zeros(7))
    assert np.array_equal(obs["robot_state"][STATE_KEY], good)
    with pytest.warns(RuntimeWarning, match="sensor bus timeout"):
        obs, *_ = wrapper.step(np.zeros(7))
    row = obs["robot_state"][STATE_KEY]
    f = field_offsets(7)
    assert row.shape == good.shape and row[f["valid"]] == 0.0  # valid = 0: the corrector passes through
    assert row[f["episode_step"]] == 2 and not row[f["obj_pos"]:].any()  # the steps still counted, nothing read
    obs, *_ = wrapper.step(np.zeros(7))
    assert wrapper.read_failures == 2
