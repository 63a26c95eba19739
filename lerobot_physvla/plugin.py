"""What lerobot's plugin auto-import runs, and the `--policy.postprocess` / `--physvla.*` flags.

lerobot imports every installed distribution named `lerobot_env_*` at the start of its console
scripts; ours (`lerobot_env_physvla`) imports this module, which
- registers the `libero_physvla` env type and the two processor steps (always);
- in `lerobot-eval` only: removes `--policy.postprocess=...` and `--physvla.<field>=<value>` from
  argv (lerobot's parser would reject them) and, for `--policy.postprocess=physvla`, installs the
  eval hook of `lerobot_compat`. `--policy.postprocess=none` or no flag leaves lerobot untouched.
Bad flags end the program with a one-line error and exit code 2. PHYSVLA_DISABLE=1 turns the
plugin off entirely.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import os
import sys
import typing
from pathlib import Path

from lerobot_physvla.core.config import PhysVLAConfig

POSTPROCESS_FLAG = "--policy.postprocess"
PREFIX = "--physvla."
CHOICES = ("physvla", "none")


class FlagError(ValueError):
    pass


def _field_types() -> dict[str, object]:
    hints = typing.get_type_hints(PhysVLAConfig)
    return {f.name: hints[f.name] for f in dataclasses.fields(PhysVLAConfig)}


def _convert(name: str, value: str, hint) -> object:
    origin = typing.get_origin(hint)
    try:
        if hint is float:
            return float(value)
        if hint is int:
            return int(value)
        if hint is bool:
            return {"true": True, "false": False}[value.lower()]
        if origin is tuple:
            items = [v for v in value.strip("[]()").replace(",", " ").split()]
            return tuple(float(v) for v in items)
    except (ValueError, KeyError):
        raise FlagError(f"--physvla.{name}={value}: not a valid {getattr(hint, '__name__', hint)}") from None
    return value


def split_argv(argv: list[str]) -> tuple[str | None, dict[str, object], list[str]]:
    """(postprocess choice or None, PhysVLAConfig overrides, argv without our flags)."""
    types = _field_types()
    post, overrides, rest = None, {}, []
    it = iter(range(len(argv)))
    skip = False
    for i in it:
        if skip:
            skip = False
            continue
        arg = argv[i]
        key, eq, value = arg.partition("=")
        if key == POSTPROCESS_FLAG or key.startswith(PREFIX):
            if not eq:
                if i + 1 >= len(argv):
                    raise FlagError(f"{key} needs a value")
                value, skip = argv[i + 1], True
            if key == POSTPROCESS_FLAG:
                if value not in CHOICES:
                    raise FlagError(f"{POSTPROCESS_FLAG}={value}: unknown; choose one of {', '.join(CHOICES)}")
                post = value
            else:
                name = key[len(PREFIX):]
                if name not in types:
                    raise FlagError(f"{key}: unknown; PhysVLA fields are {', '.join(types)}")
                overrides[name] = _convert(name, value, types[name])
        else:
            rest.append(arg)
    return post, overrides, rest


def build_config(overrides: dict[str, object]) -> PhysVLAConfig:
    try:
        return PhysVLAConfig(**overrides)
    except ValueError as e:
        raise FlagError(str(e)) from None


def _write_diagnostics(cfg, step) -> None:
    recorder = getattr(step, "_physvla_recorder", None)
    if recorder is None or cfg.output_dir is None:
        return
    from lerobot.envs.libero import TASK_SUITE_MAX_STEPS

    task = str(getattr(cfg.env, "task", "")).split(",")[0]
    recorder.horizon = getattr(cfg.env, "episode_length", None) or TASK_SUITE_MAX_STEPS.get(task)
    info = Path(cfg.output_dir) / "eval_info.json"
    if info.is_file():
        per_task = json.loads(info.read_text()).get("per_task", [])
        recorder.apply_env_successes({int(t["task_id"]): t["metrics"]["successes"] for t in per_task})
    path = recorder.write(cfg.output_dir, config=step.config)
    counts = dict(step.passthrough_counts) or "none"
    logging.info("physvla: diagnostics written to %s (pass-throughs: %s)", path, counts)
    print(f"physvla: diagnostics in {Path(path).parent} (physvla_diagnostics.json, physvla_episodes.jsonl)")


def activate_eval(argv: list[str]) -> None:
    """Strip our flags from argv in place and install the eval hook if asked. Exits 2 on bad flags."""
    from lerobot_physvla import compat as lerobot_compat
    from lerobot_physvla.diagnostics import EpisodeRecorder
    from lerobot_physvla.processor.physvla_processor import PhysVLACorrectorStep

    try:
        post, overrides, rest = split_argv(argv[1:])
        if overrides and post != "physvla":
            raise FlagError("--physvla.* flags need --policy.postprocess=physvla")
        cfg = build_config(overrides) if post == "physvla" else None
        if cfg is not None:
            lerobot_compat.check_lerobot_version()
    except (FlagError, lerobot_compat.UnsupportedLerobot) as e:
        print(f"lerobot-physvla: error: {e}", file=sys.stderr)
        raise SystemExit(2) from None
    argv[1:] = rest
    if cfg is None:
        return

    def attach(step):  # record every step of the evaluation (also a checkpoint's own corrector)
        if getattr(step, "_physvla_recorder", None) is None:
            step._physvla_recorder = EpisodeRecorder(
                save_states=os.environ.get("PHYSVLA_SAVE_STATES") == "1", gripper_index=step.cfg.action_layout.gripper
            )
            step.listeners.append(step._physvla_recorder)
        return step

    def make_step():
        return attach(PhysVLACorrectorStep(config=cfg.to_dict()))

    lerobot_compat.install_eval_hook(make_step, _write_diagnostics, attach)


def _is_lerobot_eval(argv0: str) -> bool:
    return Path(argv0).name in ("lerobot-eval", "lerobot_eval.py", "lerobot-physvla-eval")


def activate(argv: list[str] | None = None) -> None:
    """Entry point of the plugin import (see module docstring)."""
    if os.environ.get("PHYSVLA_DISABLE") == "1":
        return
    from lerobot_physvla.envs import libero_physvla as lerobot_envs
    from lerobot_physvla.processor import physvla_processor as lerobot_steps
    from lerobot_physvla.policies import physvla_scripted as scripted_policy  # noqa: F401 - registers types and steps

    argv = sys.argv if argv is None else argv
    if argv and _is_lerobot_eval(argv[0]):
        activate_eval(argv)


def eval_main() -> None:
    """`lerobot-physvla-eval`: lerobot-eval with the same arguments (the flags work the same)."""
    from lerobot.scripts import lerobot_eval
    from lerobot.utils.import_utils import register_third_party_plugins
    from lerobot.utils.utils import init_logging

    init_logging()
    activate(sys.argv)
    register_third_party_plugins()
    lerobot_eval.eval_main()

