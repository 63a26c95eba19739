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
