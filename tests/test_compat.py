import pytest

from lerobot.envs.configs import LiberoEnv

from lerobot_physvla.compat import UnsupportedLerobot, as_physvla_env, check_lerobot_version
from lerobot_physvla.envs.libero_physvla import LiberoPhysVLAEnvConfig


def test_supported_version_passes_and_others_name_the_fix():
    check_lerobot_version()  # the installed one
    with pytest.raises(UnsupportedLerobot, match=r"found 0\.5\.0: pip install 'lerobot\[libero\]==0\.6\.1'"):
        check_lerobot_version("0.5.0")


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
