"""The `--policy.postprocess` and `--physvla.*` flags: parsing, type conversion, and the config they build.

    --policy.postprocess=physvla|none     turn the corrector on (off: lerobot untouched)
    --physvla.preset=<name>               start from a named preset (core.config.PRESETS):
                                          default | paper | paper_alg1 | smooth | shift | arm
    --physvla.<field>=<value>             any PhysVLAConfig field (mode, cap, weighting, ...)
    --physvla.help                        print every field (group, type, default, meaning) and exit

Which configuration the flags build: the preset `--physvla.preset` names (without one: `default`, the
evidence-chosen default, docs/method.md; lerobot-rollout: `arm`), and each `--physvla.<field>` changes that
field alone (`--physvla.mode=phys_el` is the default with Branch B on; the paper's main text is
`--physvla.preset=paper`). Old field names (core/config.py ALIASES) are accepted with a warning.

lerobot's own parser rejects unknown flags, so they are taken out of argv before it runs.
"""

from __future__ import annotations

import dataclasses
import types
import typing

from lerobot_physvla.core.config import (ALIASES, DEFAULT_PRESET, EXPERIMENTAL_GROUP, GROUPS, PRESETS, PhysVLAConfig,
                                         differing, preset, renamed)

POSTPROCESS_FLAG = "--policy.postprocess"
PREFIX = "--physvla."
HELP_FLAG = "--physvla.help"
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
                                  "arm_geometry": bool,
                                  # object / target positions from ArUco markers in a camera frame (sources/markers.py)
                                  "pose_source": str, "camera": str, "object_marker": int, "target_marker": int,
                                  "marker_size_m": float, "calibration": str, "marker_dictionary": str,
                                  "marker_max_error_m": float, "object_marker_offset": tuple[float, ...],
                                  "target_marker_offset": tuple[float, ...]}


def split_argv(argv: list[str], robot: bool = False) -> tuple[str | None, dict[str, object], list[str]]:
    """(postprocess choice or None, PhysVLAConfig overrides (and, with robot, ROBOT_FLAGS values),
    argv without our flags)."""
    types = {**_field_types(), **(ROBOT_FLAGS if robot else {})}
    types.update({old: types[new] for old, new in ALIASES.items()})
    if HELP_FLAG in argv:
        print(help_text(robot))
        raise SystemExit(0)
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
    return post, renamed(overrides), rest


def _type_name(hint) -> str:
    args, origin = typing.get_args(hint), typing.get_origin(hint)
    if origin is typing.Literal:
        return " | ".join(map(str, args))
    if origin is types.UnionType or origin is typing.Union:
        return " | ".join(_type_name(a) for a in args)
    if origin is tuple:
        return "[" + ", ".join("..." if a is Ellipsis else _type_name(a) for a in args) + "]"
    return getattr(hint, "__name__", None) or str(hint).replace("typing.", "")


def help_text(robot: bool = False) -> str:
    """Every `--physvla.*` flag: by group, each field's type, default (the `default` preset) and meaning; the
    experimental fields apart; with `robot`, the robot step's flags (lerobot-rollout)."""
    types, d = _field_types(), PhysVLAConfig()
    lines = ["--physvla.* flags (lerobot-physvla). --physvla.preset=<name> picks the starting point: "
             + ", ".join(PRESETS) + f" (without it: {DEFAULT_PRESET}{'; lerobot-rollout: arm' if robot else ''}); "
             "each --physvla.<field>=<value> then changes that field alone. Defaults below are the default preset's.",
             ""]
    for heading, fields in GROUPS:
        lines.append(("EXPERIMENTAL (" + heading.partition(": ")[2] + ")") if heading == EXPERIMENTAL_GROUP
                     else heading.capitalize())
        for f in fields:
            note = f"  [{f.experimental}]" if f.experimental else ""
            lines.append(f"  --physvla.{f.name}  ({_type_name(types[f.name])}, default {getattr(d, f.name)!r})"
                         f"  {f.doc}{note}")
        lines.append("")
    if ALIASES:
        lines.append("Old names, accepted with a warning: " + ", ".join(f"{o} -> {n}" for o, n in ALIASES.items()))
    if robot:
        lines += ["", "The robot step (lerobot-rollout): " + ", ".join(f"--physvla.{k}" for k in ROBOT_FLAGS)
                  + " (docs/arms.md)"]
    return "\n".join(lines)


def describe(cfg: PhysVLAConfig, overrides: dict[str, object], default: str = DEFAULT_PRESET) -> str:
    """One line: the preset the flags resolved to and the fields that differ from it."""
    name = str(overrides.get("preset") or default)
    diff = differing(cfg, name)
    said = ", ".join(f"{k}={v!r}" for k, v in diff.items()) if diff else "none"
    return f"lerobot-physvla: preset {name}; fields that differ from it: {said}"


def build_config(overrides: dict[str, object], default: str = DEFAULT_PRESET) -> PhysVLAConfig:
    """The configuration the flags ask for (module doc): the preset they name, else `default` (lerobot-rollout:
    `arm`), with each named field changed."""
    overrides = dict(overrides)
    name = overrides.pop("preset", None) or default
    try:
        return preset(name, **overrides)
    except (ValueError, TypeError) as e:
        raise FlagError(str(e)) from None
