"""lerobot-rollout's flags: stripped before lerobot parses argv, bad ones stop it with one line."""

from __future__ import annotations

import pytest

from lerobot_physvla.scripts.lerobot_physvla_rollout import activate_rollout


@pytest.fixture
def restore_rollout():
    from lerobot.scripts import lerobot_rollout

    original = lerobot_rollout.build_rollout_context
    yield lerobot_rollout
    lerobot_rollout.build_rollout_context = original


def test_our_flags_are_taken_out_and_the_hook_carries_the_step(restore_rollout):
    argv = ["lerobot-rollout", "--robot.type=so101_follower", "--fps=15", "--policy.postprocess=physvla",
            "--physvla.arm=so101", "--physvla.object_xyz=[0.25,0,0.02]", "--physvla.target_key", "target",
            "--physvla.mode=phys"]
    activate_rollout(argv)
    assert argv == ["lerobot-rollout", "--robot.type=so101_follower", "--fps=15"]
    step = restore_rollout.build_rollout_context.step
    assert step.arm == "so101" and step.fps == 15.0 and step.object_xyz == [0.25, 0.0, 0.02]
    assert step.target_key == "target" and step.cfg.mode == "phys"


def test_no_flag_leaves_lerobot_rollout_untouched(restore_rollout):
    original = restore_rollout.build_rollout_context
    argv = ["lerobot-rollout", "--robot.type=so101_follower"]
    activate_rollout(argv)
    assert argv == ["lerobot-rollout", "--robot.type=so101_follower"]
    assert restore_rollout.build_rollout_context is original


@pytest.mark.parametrize("flags, message", [
    (["--policy.postprocess=physvla", "--physvla.arm=ur5", "--physvla.object_xyz=[0,0,0]",
      "--physvla.target_xyz=[0,0,0]"], "unknown arm 'ur5'; known:"),
    (["--physvla.arm=so101"], "--physvla.* flags need --policy.postprocess=physvla"),
    (["--policy.postprocess=physvla", "--physvla.arm=so101"], "object's and the target's position"),
    (["--policy.postprocess=physvla", "--physvla.object_xyz=[a,b]"], "not a valid"),
])
def test_bad_flags_stop_before_anything_is_built(flags, message, capsys, restore_rollout):
    with pytest.raises(SystemExit) as e:
        activate_rollout(["lerobot-rollout", *flags])
    assert e.value.code == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("lerobot-physvla: error:") and message in err and "\n" not in err
