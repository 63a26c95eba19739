"""`lerobot-physvla-config`: add the corrector to a policy checkpoint's postprocessor.

    lerobot-physvla-config POLICY_DIR [--preset default] [--mode phys_el] [--physvla.<field>=<value> ...]
    lerobot-physvla-config --write-presets configs
    lerobot-physvla-config POLICY_DIR --physvla.arm=so101 --physvla.object_key=block --physvla.target_xyz=[0.3,-0.2,0]

With no flag it adds the `default` preset (the evidence-chosen default, docs/method.md); `--mode`
alone gives that mode of the paper (main-text settings), `--preset` any named preset (flags as
in lerobot_physvla.flags).

Loads POLICY_DIR/policy_postprocessor.json with lerobot's own PolicyProcessorPipeline, appends
(or replaces) the PhysVLACorrectorStep, and saves it back with `save_pretrained`: the entry is
written in the `"class"` form, so any interpreter loading it imports lerobot_physvla by itself.
The directory can then be pushed to the hub like any checkpoint.

With `--physvla.arm` (and the arm's flags of lerobot-rollout: object / target, filter, noise) it
instead saves the arm's corrector (PhysVLARobotActionStep) as POLICY_DIR/physvla_robot_processor.json,
which `lerobot-rollout --policy.path=POLICY_DIR --policy.postprocess=physvla` applies.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from lerobot_physvla.core.config import ARM_PRESET, DEFAULT_PRESET, MODES, PRESETS, PhysVLAConfig

POSTPROCESSOR = "policy_postprocessor.json"


def add_corrector(policy_dir: str | Path, cfg: PhysVLAConfig) -> Path:
    """Append the corrector to POLICY_DIR's postprocessor (creating one if it has none)."""
    from lerobot.processor import PolicyProcessorPipeline
    from lerobot.processor.converters import policy_action_to_transition, transition_to_policy_action

    from lerobot_physvla.processor.physvla_processor import PhysVLACorrectorStep

    d = Path(policy_dir)
    if (d / POSTPROCESSOR).is_file():
        post = PolicyProcessorPipeline.from_pretrained(
            d, config_filename=POSTPROCESSOR, to_transition=policy_action_to_transition,
            to_output=transition_to_policy_action,
        )
        post.steps = [s for s in post.steps if not isinstance(s, PhysVLACorrectorStep)]
    else:
        d.mkdir(parents=True, exist_ok=True)
        post = PolicyProcessorPipeline(
            steps=[], name="policy_postprocessor", to_transition=policy_action_to_transition,
            to_output=transition_to_policy_action,
        )
    steps = 1  # actions the policy executes open loop per call (its n_action_steps): chunk_phase_caps
    if (d / "config.json").is_file():
        steps = int(json.loads((d / "config.json").read_text()).get("n_action_steps", 1) or 1)
    post.steps.append(PhysVLACorrectorStep(config=cfg.for_policy(steps).to_dict()))
    post.save_pretrained(d, config_filename=POSTPROCESSOR)
    return d / POSTPROCESSOR


def add_robot_corrector(policy_dir: str | Path, cfg: PhysVLAConfig, robot: dict) -> Path:
    """Save the arm's corrector step (fields: ROBOT_FLAGS values) as POLICY_DIR/physvla_robot_processor.json."""
    from lerobot.processor import RobotProcessorPipeline
    from lerobot.processor.converters import robot_action_observation_to_transition, transition_to_robot_action

    from lerobot_physvla.processor.physvla_robot_step import PhysVLARobotActionStep
    from lerobot_physvla.scripts.lerobot_physvla_rollout import ROBOT_PROCESSOR

    fields = {k: list(v) if k.endswith(("_xyz", "_offset")) else v for k, v in robot.items()}
    step = PhysVLARobotActionStep(config=cfg.to_dict(), **fields)  # checked now: arm, points, keys
    pipe = RobotProcessorPipeline(steps=[step], name="physvla_robot_processor",
                                  to_transition=robot_action_observation_to_transition,
                                  to_output=transition_to_robot_action)
    d = Path(policy_dir)
    d.mkdir(parents=True, exist_ok=True)
    pipe.save_pretrained(d, config_filename=ROBOT_PROCESSOR)
    return d / ROBOT_PROCESSOR


def main(argv: list[str] | None = None) -> None:
    from lerobot_physvla.flags import FlagError, build_config, split_argv

    argv = sys.argv[1:] if argv is None else argv
    from lerobot_physvla.flags import ROBOT_FLAGS
    from lerobot_physvla.arms.model import ArmError

    try:
        _, overrides, rest = split_argv(argv, robot=True)
    except FlagError as e:
        print(f"lerobot-physvla-config: error: {e}", file=sys.stderr)
        raise SystemExit(2) from None
    ap = argparse.ArgumentParser(prog="lerobot-physvla-config", description=__doc__.split("\n\n")[0])
    ap.add_argument("policy_dir", nargs="?", help="a local policy checkpoint directory")
    ap.add_argument("--mode", choices=MODES, default=None, help="shorthand for --physvla.mode")
    ap.add_argument("--preset", choices=tuple(PRESETS), default=None, help="shorthand for --physvla.preset")
    ap.add_argument("--write-presets", metavar="DIR",
                    help="write one postprocessor per paper mode (DIR/<mode>/) and per preset (DIR/preset_<name>/)")
    args = ap.parse_args(rest)
    if args.mode:
        overrides["mode"] = args.mode
    if args.preset:
        overrides["preset"] = args.preset
    robot = {k: overrides.pop(k) for k in ROBOT_FLAGS if k in overrides}
    try:
        cfg = build_config(overrides, default=ARM_PRESET if robot else DEFAULT_PRESET)
    except FlagError as e:
        print(f"lerobot-physvla-config: error: {e}", file=sys.stderr)
        raise SystemExit(2) from None
    if args.write_presets:
        for mode in MODES:  # the paper's four modes, main-text settings
            path = add_corrector(Path(args.write_presets) / mode,
                                 build_config({**overrides, "preset": "paper", "mode": mode}))
            print(f"wrote {path}")
        for name in PRESETS:
            path = add_corrector(Path(args.write_presets) / f"preset_{name}", build_config({**overrides, "preset": name}))
            print(f"wrote {path}")
    elif args.policy_dir and robot:
        try:
            print(f"wrote {add_robot_corrector(args.policy_dir, cfg, robot)}")
        except ArmError as e:
            print(f"lerobot-physvla-config: error: {e}", file=sys.stderr)
            raise SystemExit(2) from None
    elif args.policy_dir:
        print(f"wrote {add_corrector(args.policy_dir, cfg)}")
    else:
        ap.error("give a POLICY_DIR or --write-presets DIR")


if __name__ == "__main__":
    main()
