import pytest

from lerobot_physvla.flags import FlagError, build_config, split_argv


def test_split_argv_takes_our_flags_and_keeps_lerobots():
    argv = ["--policy.path=p", "--policy.postprocess=physvla", "--physvla.mode", "phys", "--physvla.cap=0.1",
            "--physvla.grasp_offset_m=[0,0,0.02]", "--env.type=libero"]
    post, overrides, rest = split_argv(argv)
    assert post == "physvla" and rest == ["--policy.path=p", "--env.type=libero"]
    assert overrides == {"mode": "phys", "cap": 0.1, "grasp_offset_m": (0.0, 0.0, 0.02)}
    cfg = build_config(overrides)
    assert cfg.cap == 0.1 and cfg.mode == "phys"


@pytest.mark.parametrize(
    "argv,message",
    [(["--policy.postprocess=x"], "unknown"), (["--physvla.nope=1"], "unknown"),
     (["--physvla.cap=abc"], "not a valid float"), (["--physvla.mode"], "needs a value")],
)
def test_bad_flags(argv, message):
    with pytest.raises(FlagError, match=message):
        split_argv(argv)


def test_bad_value_is_a_flag_error():
    with pytest.raises(FlagError, match="cap"):
        build_config({"cap": 2.0})


def test_which_configuration_the_flags_build():
    from lerobot_physvla.core.config import PRESETS, PhysVLAConfig

    assert build_config({}) == PRESETS["default"]  # --policy.postprocess=physvla alone
    assert build_config({"mode": "phys_el"}) == PhysVLAConfig.paper(mode="phys_el")  # a paper mode, one flag away
    assert build_config({"preset": "paper_alg1"}) == PRESETS["paper_alg1"]
    assert build_config({"preset": "default", "lowpass": "off"}) == PRESETS["default"].replace(lowpass="off")
    _, overrides, _ = split_argv(["--physvla.preset=paper", "--physvla.phase_caps=0,0,0,1"])
    assert build_config(overrides) == PhysVLAConfig.paper(mode="phys_el", phase_caps=(0.0, 0.0, 0.0, 1.0))
    with pytest.raises(FlagError, match="choose one of"):
        split_argv(["--physvla.preset=turbo"])
