"""The `--policy.postprocess` and `--physvla.*` flags: parsing, type conversion, and the config they build.

    --policy.postprocess=physvla|none     turn the corrector on (off: lerobot untouched)
    --physvla.preset=<name>               start from a named preset (core.config.PRESETS):
                                          default | paper | paper_alg1 | smooth | arm
    --physvla.<field>=<value>             any PhysVLAConfig field (mode, cap, weighting, ...)

Which configuration the flags build:
- no preset and no mode: the `default` preset (the evidence-chosen default, docs/method.md);
- `--physvla.mode=<mode>` without a preset: that mode of the paper (main-text settings, the
  `paper` preset), so the paper's modes stay one flag away;
- `--physvla.preset=<name>`: that preset; any other `--physvla.*` flag overrides its field.

lerobot's own parser rejects unknown flags, so they are taken out of argv before it runs.
"""

from __future__ import annotations

import dataclasses
import typing

from lerobot_physvla.core.config import DEFAULT_PRESET, PRESETS, PhysVLAConfig, preset

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


# the flags of the robot-side step (lerobot-rollout): PhysVLARobotActionStep's fields
ROBOT_FLAGS: dict[str, object] = {"arm": str, "object_xyz": tuple[float, ...], "target_xyz": tuple[float, ...],
                                  "object_key": str, "target_key": str, "pose_age_key": str, "velocity_cutoff_hz": float,
                                  "state_delay_s": float, "reading_noise_deg": float, "noise_snr_min": float,
                                  "arm_geometry": bool}


def split_argv(argv: list[str], robot: bool = False) -> tuple[str | None, dict[str, object], list[str]]:
    """(postprocess choice or None, PhysVLAConfig overrides (and, with robot, ROBOT_FLAGS values),
    argv without our flags)."""
    types = {**_field_types(), **(ROBOT_FLAGS if robot else {})}
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
                if name == "preset":
                    if value not in PRESETS:
                        raise FlagError(f"{key}={value}: unknown; choose one of {', '.join(PRESETS)}")
                    overrides[name] = value
                    continue
                if name not in types:
                    raise FlagError(f"{key}: unknown; PhysVLA fields are preset, {', '.join(types)}")
                overrides[name] = _convert(name, value, types[name])
        else:
            rest.append(arg)
    return post, overrides, rest


def build_config(overrides: dict[str, object], default: str = DEFAULT_PRESET) -> PhysVLAConfig:
    """The configuration the flags ask for (module doc: the `default` preset, paper mode, or
    preset); `default` names the preset used when no flag names one (lerobot-rollout: `arm`)."""
    overrides = dict(overrides)
    name = overrides.pop("preset", None)
    if name is None:
        name = "paper" if "mode" in overrides else default
    try:
        return preset(name, **overrides)
    except (ValueError, TypeError) as e:
        raise FlagError(str(e)) from None
