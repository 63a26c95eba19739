"""`lerobot-rollout --policy.postprocess=physvla --physvla.arm=...`: the corrector on a robot arm.

    lerobot-rollout --robot.type=so101_follower --policy.path=P --policy.postprocess=physvla \\
        --physvla.arm=so101 --physvla.object_xyz=[0.25,0,0.02] --physvla.target_xyz=[0.2,0.15,0.02]

`activate_rollout(argv)` takes our flags out of argv (lerobot's parser would reject them), builds
`PhysVLARobotActionStep` (arm, object / target points or keys, `--physvla.*` corrector fields as
in lerobot-eval, the rollout's `--fps`) and wraps lerobot-rollout's `build_rollout_context` so
that its robot action processor runs lerobot's steps, then ours. Bad flags or an unknown arm stop
the program before anything is built, with one line and exit code 2.
"""

from __future__ import annotations

import sys

from lerobot_physvla import compat
from lerobot_physvla.flags import ROBOT_FLAGS, FlagError, build_config, split_argv
from lerobot_physvla.robots.arms import ArmError


def _fps(argv: list[str]) -> float:
    for i, arg in enumerate(argv):
        key, eq, value = arg.partition("=")
        if key == "--fps":
            return float(value if eq else argv[i + 1])
    return 30.0  # RolloutConfig's default


def activate_rollout(argv: list[str]) -> None:
    """Strip our flags from argv in place and install the rollout hook if asked. Exits 2 on bad flags."""
    from lerobot_physvla.processor.physvla_robot_step import PhysVLARobotActionStep

    try:
        post, overrides, rest = split_argv(argv[1:], robot=True)
        robot = {k: overrides.pop(k) for k in ROBOT_FLAGS if k in overrides}
        if (overrides or robot) and post != "physvla":
            raise FlagError("--physvla.* flags need --policy.postprocess=physvla")
        if post == "physvla":
            compat.check_lerobot_version()
            cfg = build_config(overrides)
            step = PhysVLARobotActionStep(
                arm=robot.get("arm", "so101"), fps=_fps(rest), config=cfg.to_dict(),
                object_xyz=list(robot["object_xyz"]) if "object_xyz" in robot else None,
                target_xyz=list(robot["target_xyz"]) if "target_xyz" in robot else None,
                object_key=robot.get("object_key"), target_key=robot.get("target_key"),
                velocity_cutoff_hz=robot.get("velocity_cutoff_hz", 5.0), state_delay_s=robot.get("state_delay_s", 0.0))
    except (FlagError, ArmError, compat.UnsupportedLerobot) as e:
        print(f"lerobot-physvla: error: {e}", file=sys.stderr)
        raise SystemExit(2) from None
    argv[1:] = rest
    if post != "physvla":
        return
    install_rollout_hook(step)


def install_rollout_hook(step) -> None:
    """lerobot-rollout's robot action processor becomes lerobot's steps followed by `step`."""
    from lerobot.processor import RobotProcessorPipeline
    from lerobot.processor.converters import robot_action_observation_to_transition, transition_to_robot_action
    from lerobot.processor.factory import make_default_robot_action_processor
    from lerobot.scripts import lerobot_rollout

    original = lerobot_rollout.build_rollout_context
    if getattr(original, "_physvla", False):
        return

    def build_rollout_context(cfg, shutdown_event, teleop_action_processor=None, robot_action_processor=None,
                              robot_observation_processor=None):
        base = robot_action_processor or make_default_robot_action_processor()
        corrected = RobotProcessorPipeline(steps=[*base.steps, step], name="robot_action_processor_physvla",
                                           to_transition=robot_action_observation_to_transition,
                                           to_output=transition_to_robot_action)
        return original(cfg, shutdown_event, teleop_action_processor, corrected, robot_observation_processor)

    build_rollout_context._physvla = True
    build_rollout_context.step = step
    lerobot_rollout.build_rollout_context = build_rollout_context
