"""`lerobot-rollout --policy.postprocess=physvla --physvla.arm=...`: the corrector on a robot arm.

    lerobot-rollout --robot.type=so101_follower --policy.path=P --policy.postprocess=physvla \\
        --physvla.arm=so101 --physvla.object_xyz=[0.25,0,0.02] --physvla.target_xyz=[0.2,0.15,0.02]

`activate_rollout(argv)` takes our flags out of argv (lerobot's parser would reject them), builds
`PhysVLARobotActionStep` (arm, object / target points or keys, `--physvla.*` corrector fields as
in lerobot-eval, the rollout's `--fps`) and wraps lerobot-rollout's `build_rollout_context` so
that its robot action processor runs lerobot's steps, then ours. Bad flags or an unknown arm stop
the program before anything is built, with one line and exit code 2.

A configuration shared with the policy: `lerobot-physvla-config POLICY_DIR --physvla.arm=so101
--physvla.object_key=block ...` saves the step as POLICY_DIR/physvla_robot_processor.json (a
lerobot RobotProcessorPipeline, pushed to the hub with the checkpoint); then
`lerobot-rollout --policy.path=POLICY_DIR --policy.postprocess=physvla` applies it, flags on the
command line overriding its fields.
"""

from __future__ import annotations

import atexit
import sys
from pathlib import Path

from lerobot_physvla import compat
from lerobot_physvla.core.config import ARM_PRESET
from lerobot_physvla.flags import ROBOT_FLAGS, FlagError, build_config, describe, split_argv
from lerobot_physvla.arms.model import ArmError

ROBOT_PROCESSOR = "physvla_robot_processor.json"  # the arm's corrector, saved beside a policy


def _fps(argv: list[str]) -> float:
    for i, arg in enumerate(argv):
        key, eq, value = arg.partition("=")
        if key == "--fps":
            return float(value if eq else argv[i + 1])
    return 30.0  # RolloutConfig's default


def _policy_path(argv: list[str]) -> str | None:
    for i, arg in enumerate(argv):
        key, eq, value = arg.partition("=")
        if key == "--policy.path":
            return value if eq else (argv[i + 1] if i + 1 < len(argv) else None)
    return None


def saved_robot_step(policy_path: str | None) -> dict | None:
    """The PhysVLARobotActionStep fields saved with a policy (`lerobot-physvla-config POLICY_DIR
    --physvla.arm=...` writes them to POLICY_DIR/ROBOT_PROCESSOR), read from a local checkpoint
    directory or its hub repository; None if it has none."""
    from lerobot.processor import RobotProcessorPipeline

    from lerobot_physvla.processor.physvla_robot_step import PhysVLARobotActionStep

    if not policy_path:
        return None
    local = Path(policy_path)
    if local.exists() and not (local / ROBOT_PROCESSOR).is_file():
        return None
    try:
        pipe = RobotProcessorPipeline.from_pretrained(policy_path, config_filename=ROBOT_PROCESSOR)
    except Exception as e:  # noqa: BLE001 - a hub repository without the file (or unreachable): no saved config
        if local.exists():
            raise FlagError(f"{local / ROBOT_PROCESSOR} does not load ({type(e).__name__}: {e}); rewrite it with "
                            "lerobot-physvla-config POLICY_DIR --physvla.arm=...") from None
        return None
    steps = [st for st in pipe.steps if isinstance(st, PhysVLARobotActionStep)]
    return steps[0].get_config() if steps else None


def activate_rollout(argv: list[str]) -> None:
    """Strip our flags from argv in place and install the rollout hook if asked. Exits 2 on bad flags.

    The step's fields come from the flags, over those saved with the policy (`saved_robot_step`)
    when it has them: a flag given on the command line wins; corrector flags (--physvla.mode,
    --physvla.preset, ...) replace the saved corrector configuration."""
    from lerobot_physvla.processor.physvla_robot_step import PhysVLARobotActionStep

    try:
        post, overrides, rest = split_argv(argv[1:], robot=True)
        robot = {k: overrides.pop(k) for k in ROBOT_FLAGS if k in overrides}
        if (overrides or robot) and post != "physvla":
            raise FlagError("--physvla.* flags need --policy.postprocess=physvla")
        if post == "physvla":
            compat.check_lerobot_version()
            said = ""
            fields = saved_robot_step(_policy_path(rest)) or {}
            if fields:
                print(f"lerobot-physvla: the arm's corrector configuration saved with the policy "
                      f"({_policy_path(rest)}/{ROBOT_PROCESSOR}); flags override it", file=sys.stderr)
            if overrides or "config" not in fields:
                cfg = build_config(overrides, default=ARM_PRESET)
                said = describe(cfg, overrides, default=ARM_PRESET)
                fields["config"] = cfg.to_dict()
            for k in ("object_xyz", "target_xyz", "object_marker_offset", "target_marker_offset"):
                if k in robot:
                    robot[k] = list(robot[k])
            for name in ("object", "target"):  # a fixed point, a key or a marker given replaces a saved other one
                given = [w for w in ("xyz", "key", "marker") if f"{name}_{w}" in robot]
                for w in ("xyz", "key", "marker"):
                    if given and w not in given:
                        fields.pop(f"{name}_{w}", None)
            fields.update(robot)
            fields["fps"] = _fps(rest)
            step = PhysVLARobotActionStep(**fields)
            if said:  # the first line, once the step is built (a bad flag's error is the only line)
                print(said, file=sys.stderr)
            if step.cfg.approach_pull_m > 0:  # off in `arm`; measured in simulation only
                print("lerobot-physvla: warning: the approach pull (approach_pull_m > 0: the `default` preset, not "
                      "`arm`) was measured in simulation only (docs/decisions/29-approach-pull.md, "
                      "36-shift-shipped.md); on this arm it will move the hand to the object and carry it, with "
                      "authority in every phase",
                      file=sys.stderr)
            if step.cfg.carry_far_m > 0:  # an option, measured in simulation only
                print("lerobot-physvla: warning: the carry to the target (carry_far_m > 0) was measured in simulation "
                      "only, on LIBERO's camera ACTs (docs/decisions/30-carry-to-target.md); on this arm it will carry "
                      "a held object over the target and set it down itself", file=sys.stderr)
    except (FlagError, ArmError, compat.UnsupportedLerobot) as e:
        print(f"lerobot-physvla: error: {e}", file=sys.stderr)
        raise SystemExit(2) from None
    argv[1:] = rest
    if post != "physvla":
        return
    install_rollout_hook(step)


def reset_with_the_policy(ctx, step) -> None:
    """`step.reset()` whenever lerobot-rollout resets the policy's inference engine: at the start,
    and at every episode of the episodic / DAgger strategies (lerobot/rollout/strategies). The
    corrector's episode memory (step counter, object's resting height, EMAs) then follows the
    policy's episodes. A context of another shape is left alone (the corrector then keeps one
    episode for the whole rollout)."""
    engine = getattr(getattr(ctx, "policy", None), "inference", None)
    reset = getattr(engine, "reset", None)
    if reset is None or getattr(reset, "_physvla", False):
        return

    def reset_both(*args, **kwargs):
        step.reset()
        return reset(*args, **kwargs)

    reset_both._physvla = True
    engine.reset = reset_both


def install_rollout_hook(step) -> None:
    """lerobot-rollout's robot action processor becomes lerobot's steps followed by `step`, and
    `step` starts an episode whenever the policy does (`reset_with_the_policy`)."""
    from lerobot.processor import RobotProcessorPipeline
    from lerobot.processor.converters import robot_action_observation_to_transition, transition_to_robot_action
    from lerobot.processor.factory import make_default_robot_action_processor
    from lerobot.scripts import lerobot_rollout

    original = lerobot_rollout.build_rollout_context
    if getattr(original, "_physvla", False):  # installed already: the new step replaces the old
        original.step = step
        return

    def build_rollout_context(cfg, shutdown_event, teleop_action_processor=None, robot_action_processor=None,
                              robot_observation_processor=None):
        base = robot_action_processor or make_default_robot_action_processor()
        corrected = RobotProcessorPipeline(steps=[*base.steps, build_rollout_context.step],
                                           name="robot_action_processor_physvla",
                                           to_transition=robot_action_observation_to_transition,
                                           to_output=transition_to_robot_action)
        ctx = original(cfg, shutdown_event, teleop_action_processor, corrected, robot_observation_processor)
        reset_with_the_policy(ctx, build_rollout_context.step)
        return ctx

    build_rollout_context._physvla = True
    build_rollout_context.step = step
    lerobot_rollout.build_rollout_context = build_rollout_context
    atexit.register(_print_summary, build_rollout_context)


def _print_summary(hook) -> None:
    """At exit of a lerobot-rollout that ran the corrector: one line of what it did."""
    if hook.step.ticks:
        print(f"lerobot-{hook.step.summary()}", file=sys.stderr)
