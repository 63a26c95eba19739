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


def test_the_arm_configuration_saved_with_the_policy_is_applied_and_flags_override_it(tmp_path, restore_rollout):
    """lerobot-physvla-config POLICY_DIR --physvla.arm=... saves the step beside the policy (what is
    pushed to the hub); lerobot-rollout --policy.path=POLICY_DIR --policy.postprocess=physvla applies it."""
    from lerobot_physvla.scripts.lerobot_physvla_config import main as config_main

    config_main([str(tmp_path), "--physvla.arm=panda", "--physvla.object_key=block", "--physvla.target_xyz=[0.5,-0.2,0]",
                 "--physvla.mode=phys_el", "--physvla.noise_snr_min=4"])
    assert (tmp_path / "physvla_robot_processor.json").is_file()
    argv = ["lerobot-rollout", f"--policy.path={tmp_path}", "--fps=15", "--policy.postprocess=physvla"]
    activate_rollout(argv)
    step = restore_rollout.build_rollout_context.step
    assert argv == ["lerobot-rollout", f"--policy.path={tmp_path}", "--fps=15"]
    assert (step.arm, step.object_key, step.target_xyz, step.fps) == ("panda", "block", [0.5, -0.2, 0.0], 15.0)
    assert step.cfg.mode == "phys_el" and step.noise_snr_min == 4.0 and step.guard is not None
    activate_rollout(["lerobot-rollout", f"--policy.path={tmp_path}", "--policy.postprocess=physvla",
                      "--physvla.target_key=goal", "--physvla.mode=phys"])  # flags win
    step = restore_rollout.build_rollout_context.step
    assert step.target_key == "goal" and step.target_xyz is None and step.cfg.mode == "phys" and step.arm == "panda"


def test_a_broken_saved_configuration_is_one_line(tmp_path, capsys, restore_rollout):
    (tmp_path / "physvla_robot_processor.json").write_text("{not json")
    with pytest.raises(SystemExit) as e:
        activate_rollout(["lerobot-rollout", f"--policy.path={tmp_path}", "--policy.postprocess=physvla"])
    err = capsys.readouterr().err.strip()
    assert e.value.code == 2 and "physvla_robot_processor.json does not load" in err and "\n" not in err


def test_saving_an_arm_configuration_for_an_unknown_arm_is_one_line(tmp_path, capsys):
    from lerobot_physvla.scripts.lerobot_physvla_config import main as config_main

    with pytest.raises(SystemExit) as e:
        config_main([str(tmp_path), "--physvla.arm=ur5", "--physvla.object_xyz=[0,0,0]", "--physvla.target_xyz=[0,0,0]"])
    err = capsys.readouterr().err.strip()
    assert e.value.code == 2 and "unknown arm 'ur5'" in err and "\n" not in err
    assert not (tmp_path / "physvla_robot_processor.json").exists()


def test_the_corrector_starts_an_episode_when_lerobot_resets_the_policy(restore_rollout, monkeypatch):
    """lerobot-rollout resets the policy's inference engine at every episode (episodic, DAgger
    strategies): the corrector's episode memory must start afresh with it."""
    from types import SimpleNamespace

    engine_resets = []
    ctx = SimpleNamespace(policy=SimpleNamespace(inference=SimpleNamespace(reset=lambda: engine_resets.append(1))))
    monkeypatch.setattr(restore_rollout, "build_rollout_context", lambda *a, **k: ctx)
    activate_rollout(["lerobot-rollout", "--policy.postprocess=physvla", "--physvla.arm=so101",
                      "--physvla.object_xyz=[0.25,0,0.02]", "--physvla.target_xyz=[0.2,0.15,0.02]"])
    built = restore_rollout.build_rollout_context(None, None)
    step = restore_rollout.build_rollout_context.step
    obs = {**{f"{m}.pos": 0.0 for m in ("shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll")},
           "gripper.pos": 50.0}
    for _ in range(3):
        step.source.read_packed(obs)
    assert step.source.episode_step == 3
    built.policy.inference.reset()
    assert engine_resets == [1] and step.source.episode_step == 0


def test_on_arms_the_default_is_the_approach_veto_with_the_arms_own_geometry(restore_rollout):
    from lerobot_physvla.core.config import PRESETS

    activate_rollout(["lerobot-rollout", "--policy.postprocess=physvla", "--physvla.arm=so101",
                      "--physvla.object_key=block", "--physvla.target_xyz=[0.2,0.1,0.02]"])
    cfg = restore_rollout.build_rollout_context.step.cfg
    arm = PRESETS["arm"]
    assert (cfg.gripper_rule, cfg.place_rule, tuple(cfg.phase_caps)) == ("veto", "decelerate", (0.0, 0.0, 0.0, 0.0))
    assert (cfg.veto_height_m, cfg.veto_reach_m) == (0.02, 0.05) != (arm.veto_height_m, arm.veto_reach_m)  # SO-101's
    activate_rollout(["lerobot-rollout", "--policy.postprocess=physvla", "--physvla.arm=so101", "--physvla.arm_geometry=false",
                      "--physvla.object_key=block", "--physvla.target_xyz=[0.2,0.1,0.02]", "--physvla.preset=default"])
    cfg = restore_rollout.build_rollout_context.step.cfg
    assert cfg.place_rule == "release_veto" and (cfg.veto_height_m, cfg.veto_reach_m) == (0.06, 0.10)


def test_the_approach_pull_and_the_carry_on_an_arm_are_warned_of_and_the_arms_default_is_not(capsys, restore_rollout):
    flags = ["lerobot-rollout", "--policy.postprocess=physvla", "--physvla.arm=so101", "--physvla.object_key=block",
             "--physvla.target_xyz=[0.2,0.1,0.02]"]
    activate_rollout(list(flags))
    assert "approach pull" not in capsys.readouterr().err
    activate_rollout([*flags, "--physvla.preset=shift", "--physvla.carry_far_m=0"])
    assert restore_rollout.build_rollout_context.step.cfg.approach_pull_m == 0.1
    err = capsys.readouterr().err
    assert "warning: the approach pull" in err and "simulation only" in err and "carry to the target" not in err
    activate_rollout([*flags, "--physvla.preset=shift"])  # the preset carries too
    assert restore_rollout.build_rollout_context.step.cfg.carry_far_m == 0.1
    err = capsys.readouterr().err
    assert "warning: the carry to the target" in err and "warning: the approach pull" in err

