"""The columns the project's recorder writes and the replay reads, beside LeRobot's own.

    action                      the action the simulator executed (float32, the layout's units)
    observation.state           what a state-based policy sees (LIBERO: eef xyz, eef axis-angle,
                                finger qpos, 8; other scenes: eef xyz, gripper opening, 4)
    observation.environment_state  object xyz, target xyz (6), m
    observation.physvla_state   the corrector's packed physical state s_t (core/state.py, float64)
    physvla.episode             [scene code, task id, seed] (int64): how to re-simulate the episode
    next.success                the scene's success after this frame's action (bool)
"""

from __future__ import annotations

import numpy as np

ACTION = "action"
STATE = "observation.state"
ENV_STATE = "observation.environment_state"
PHYSVLA_STATE = "observation.physvla_state"
EPISODE = "physvla.episode"
SUCCESS = "next.success"

# scene codes of physvla.episode[0]; a LIBERO scene is "<suite>/<task id>" with the task id in [1]
SCENES: tuple[str, ...] = ("libero_spatial", "lift", "lift_plate", "fetch_pick_place")
RESIM_SCENES: tuple[str, ...] = ("libero_spatial", "lift", "lift_plate")  # re-simulation is supported here


def episode_code(scene_name: str, seed: int) -> np.ndarray:
    """physvla.episode of a scene name ("libero_spatial/3", "lift", ...) and seed."""
    family, _, task = scene_name.partition("/")
    if family not in SCENES:
        raise ValueError(f"physvla: scene {scene_name!r} has no code; known: {', '.join(SCENES)}")
    return np.array([SCENES.index(family), int(task or 0), int(seed)], dtype=np.int64)


def scene_of(code) -> tuple[str, int]:
    """(scene name, seed) of a physvla.episode value."""
    family, task, seed = (int(v) for v in code)
    if not 0 <= family < len(SCENES):
        raise ValueError(f"physvla: scene code {family} is unknown (0-{len(SCENES) - 1})")
    name = SCENES[family]
    return (f"{name}/{task}" if name.startswith("libero_") else name), seed
