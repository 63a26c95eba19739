"""Branch A's corrections, one per file, each declaring itself (`base.Correction`): its phase, its kernel,
its parameters and memory, when the configuration turns it on and what it replaces.

    approach_veto        approach: premature-grasp veto (gripper <- open)              App. A
    grasp_guidance       grasp: blend toward the grasp waypoint p* = p_obj + offset      App. A
    transport_smoothing  transport: lift bias + EMA on the position channels             App. A
    place_deceleration   place: deceleration ramp min(1, d_tgt_xy / d_thresh)            eq. 5
    temporal_ema         the `temporal` mode's uniform EMA (the paper's smoothing foil)

Beyond the paper (docs/method.md; how each was chosen: docs/decisions/): place_redirect, release_veto,
release_assist (place), lift_assist (grasp), rim_guide (approach), rim_guide_grasp (grasp), centre_guide (grasp)
and centre_guide_approach (the same pull in the approach phase), approach_pull (approach; approach_pull_grasp and
approach_pull_carry carry it on) and carry_to_target (transport; carry_to_target_place carries it on).

This module collects the declarations (CORRECTIONS, in slots.files() order) and turns a configuration into
the parameter vector p (`params`); `lerobot_physvla.core.branch_a` assembles the per-phase dispatch from
them (eq. 3).
"""

from __future__ import annotations

import importlib

import numpy as np

from lerobot_physvla.core.corrections import slots
from lerobot_physvla.core.corrections.base import (GRIPPER_CLOSED, GRIPPER_OPEN, HIGH, LOW, METRES_PER_UNIT,
                                                   PHASE_REF_OBJECT, POSE_ERROR_M, POSE_MAX_AGE, POSE_NOISE_M)
from lerobot_physvla.core.corrections.base import Correction  # noqa: F401  (re-exported)

CORRECTIONS: tuple = tuple(importlib.import_module(f"{__name__}.{f.stem}").CORRECTION for f in slots.files())
for _c, _f in zip(CORRECTIONS, slots.files()):
    if _c.name != _f.stem:
        raise RuntimeError(f"corrections/{_f.name} declares a correction named {_c.name!r}: name it after its file")
BY_NAME = {c.name: c for c in CORRECTIONS}
# the paper's kernels by name, as before they declared themselves (the package's attributes of these names)
approach_veto, grasp_guidance, place_deceleration, temporal_ema, transport_smoothing = (
    BY_NAME[n].kernel for n in ("approach_veto", "grasp_guidance", "place_deceleration", "temporal_ema",
                                "transport_smoothing"))


def channel_index(layout) -> np.ndarray:
    """idx for a layout: [x, y, z, gripper or -1]."""
    return np.array([*layout.pos, -1 if layout.gripper is None else layout.gripper], dtype=np.intp)


def active(cfg) -> set[str]:
    """The corrections the configuration turns on, less those a turned-on correction replaces."""
    on = {c.name for c in CORRECTIONS if c.on(cfg)}
    return on - {r for name in on for r in BY_NAME[name].replaces}


def params(cfg, layout) -> np.ndarray:
    """p for a configuration and layout: the shared slots, each correction's on-flag and its parameters
    (units as its declaration names them; metres converted to action units where the name says _U)."""
    p = np.zeros(slots.N_PARAMS)
    p[METRES_PER_UNIT], p[GRIPPER_OPEN] = layout.metres_per_unit, layout.gripper_open
    p[GRIPPER_CLOSED] = layout.gripper_shut
    p[LOW], p[HIGH] = layout.low, layout.high
    p[PHASE_REF_OBJECT] = cfg.phase_ref == "object"
    p[POSE_ERROR_M], p[POSE_MAX_AGE] = cfg.pose_error_told_m, cfg.pose_max_age_steps
    p[POSE_NOISE_M] = cfg.pose_noise_m
    on = active(cfg)
    for c in CORRECTIONS:
        p[slots.ON[c.name]] = c.name in on
        for name, value in c.values.items():
            p[slots.P_SLOTS[name]] = value(cfg, layout)
    return p
