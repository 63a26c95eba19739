"""The `--policy.postprocess` and `--physvla.*` flags: parsing, type conversion, and the config they build.

    --policy.postprocess=physvla|none     turn the corrector on (off: lerobot untouched)
    --physvla.<field>=<value>             any PhysVLAConfig field (mode, cap, weighting, ...)

lerobot's own parser rejects unknown flags, so they are taken out of argv before it runs.
"""

from __future__ import annotations

import dataclasses
import typing

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
