"""LIBERO scenes built directly from hf-libero, with or without cameras (no LeRobot import).

`make_libero_env` builds LIBERO's `ControlEnv`; with `cameras=False` it skips the offscreen
renderer and camera observations entirely (~10 ms a control step here instead of ~600 ms),
which is what makes sweeps and tests of state-based policies feasible.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from lerobot_physvla.sim import libero_pro, libero_setup

NO_OP = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -1.0])  # LIBERO's dummy action (gripper open)
SETTLE_STEPS = 10  # no-op steps after reset, as lerobot's LiberoEnv (num_steps_wait)


@dataclass
class LiberoTask:
    suite: str
    task_id: int
    name: str
    language: str
    bddl_file: str
    init_states: np.ndarray  # (N, state_dim)


def load_task(suite: str, task_id: int) -> LiberoTask:
    """Task `task_id` of a LIBERO suite (hf-libero's: libero_spatial, ...) or of a LIBERO-PRO suite (libero_pro.py:
    libero_object_swap, libero_spatial_with_milk, ...), its init states loaded."""
    libero_setup.check()
    if libero_pro.is_pro_suite(suite):
        t = libero_pro.task(suite, task_id)
        return LiberoTask(suite, task_id, t.name, t.language, t.bddl_path, libero_pro.init_states(t))
    import torch
    from libero.libero import benchmark, get_libero_path

    bench = benchmark.get_benchmark_dict()
    if suite not in bench:
        raise ValueError(f"physvla: unknown LIBERO suite {suite!r}; available: {sorted(bench)} and LIBERO-PRO's "
                         "<suite>_<variant> (sim/libero_pro.py available())")
    s = bench[suite]()
    if not 0 <= task_id < s.n_tasks:
        raise ValueError(f"physvla: task_id {task_id} out of range [0, {s.n_tasks - 1}] for {suite}")
    task = s.get_task(task_id)
    bddl = os.path.join(get_libero_path("bddl_files"), task.problem_folder, task.bddl_file)
    init_path = os.path.join(get_libero_path("init_states"), task.problem_folder, task.init_states_file)
    init_states = torch.load(init_path, weights_only=False)  # nosec B614: LIBERO's own numpy pickle
    return LiberoTask(suite, task_id, task.name, task.language, bddl, np.asarray(init_states))


def make_libero_env(task: LiberoTask, cameras: bool = False, camera_size: int = 256, control_freq: int = 20,
                    renderer: bool = False, camera_names: tuple[str, ...] = ("agentview", "robot0_eye_in_hand")):
    """LIBERO ControlEnv for `task` (reset once, so the inner robosuite env exists). With cameras, robosuite renders
    `camera_names` (camera_size x camera_size each) into every observation, as lerobot's LiberoEnv renders both
    (~0.13 s a camera a step on this CPU); with only `renderer`, it builds the offscreen renderer and renders
    nothing until asked (`env.env.sim.render(camera_name=...)`)."""
    from libero.libero.envs.env_wrapper import ControlEnv, OffScreenRenderEnv

    if cameras:
        env = OffScreenRenderEnv(
            bddl_file_name=task.bddl_file, camera_heights=camera_size, camera_widths=camera_size,
            control_freq=control_freq, camera_names=list(camera_names),
        )
    else:
        env = ControlEnv(
            bddl_file_name=task.bddl_file, has_renderer=False, has_offscreen_renderer=renderer,
            use_camera_obs=False, control_freq=control_freq,
        )
    env.reset()
    return env


def reset_to_init_state(env, task: LiberoTask, index: int, settle_steps: int = SETTLE_STEPS):
    """Reset to the task's init state `index` and settle with no-op steps; returns the raw obs.

    Seeds the env with `index` first (as lerobot's LiberoEnv does with its seed): robosuite's
    reset draws the controller's initial-joint reference from numpy's global RNG, and that
    reference survives `set_init_state`, so without it an episode depends on the ones before it.
    """
    env.seed(index)
    env.reset()
    obs = env.set_init_state(task.init_states[index % len(task.init_states)])
    for _ in range(settle_steps):
        obs, _, _, _ = env.step(NO_OP)
    return obs
