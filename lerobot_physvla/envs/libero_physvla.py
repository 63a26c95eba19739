"""Env type `libero_physvla`: lerobot's LIBERO env plus the physical-state export, optionally camera-free.

    lerobot-eval --env.type=libero_physvla --env.task=libero_spatial [--env.cameras=false] ...

Each sub-env (in the main process or an async worker) is lerobot's own `LiberoEnv` inside
`PhysVLAStateExport`, a gym.Wrapper that adds to every observation
    robot_state["physvla_state"]  the packed PhysState of this env (see state.py)
    robot_state["physvla_extra"]  [task_id, is_success, the action executed last step (7)]
and, with cameras=false, builds LIBERO without its offscreen renderer (~10 ms a step here instead
of ~600 ms), returns no pixels, and adds `environment_state` = [object xyz, target xyz] so
state-based policies have the scene. The env processors put `PhysVLAStateCaptureStep` first.

The `pose_*` fields put a perception model (sources/perception.py: per-episode bias, per-step noise,
lag, dropouts) between the simulator and the exported physvla_state, as a real robot's perception
would report the object's and the target's poses; the policy's own observation (environment_state
included) stays exact:

    lerobot-eval ... --env.type=libero_physvla --env.pose_bias_m=0.02 --env.pose_noise_m=0.01 \
        --policy.postprocess=physvla --physvla.pose_error_m=0.04
"""

from __future__ import annotations

import dataclasses
import warnings
from dataclasses import dataclass
from functools import partial

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from lerobot.configs.types import FeatureType, PolicyFeature
from lerobot.envs.configs import EnvConfig
from lerobot.envs.configs import LiberoEnv as LiberoEnvConfig
from lerobot.processor import PolicyProcessorPipeline
from lerobot.processor.env_processor import LiberoProcessorStep
from lerobot.utils.constants import OBS_ENV_STATE, OBS_IMAGES

from lerobot_physvla import compat
from lerobot_physvla.processor.physvla_processor import EXTRA_KEY, STATE_KEY, PhysVLAStateCaptureStep
from lerobot_physvla.core.state import UNSUPPORTED_GOAL_VALID, field_offsets, packed_size
from lerobot_physvla.sources.perception import Perception, PerceptionConfig

N_JOINTS = 7  # the Panda of LIBERO
ENV_STATE_DIM = 6  # object xyz, target xyz
_BLANK_FRAME = np.zeros((64, 64, 3), np.uint8)  # what render() shows with cameras off
_F = field_offsets(N_JOINTS)
_OBJ, _TGT = _F["obj_pos"], _F["target_pos"]
_WARNED_GOALS: set[str] = set()  # goals outside the model already said, once per process


class PhysVLAStateExport(gym.Wrapper):
    """Adds the physical state of one LIBERO sub-env to its observations (see module docstring).

    Attributes:
        cameras: False builds LIBERO with no renderer and returns no pixels.
        task_id: the LIBERO task id (exported in physvla_extra).
        read_failures: state reads that raised (those steps export an invalid state: no correction).
        unsupported_goal: the task's goal in words where it is outside what the corrector models (no On / In
            predicate: a drawer, a stove, a push); its rows export valid = -1 and pass through as unsupported_goal.
        perception: the perception model between the simulator and physvla_state (None: exact poses).
    """

    def __init__(self, env, cameras: bool = True, perception: PerceptionConfig | None = None):
        super().__init__(env)
        self.cameras = cameras
        self.perception = None if perception is None or perception.exact else Perception(perception)
        self.source = None
        self.read_failures = 0  # reads of the state source that raised (those rows export valid = 0)
        self.unsupported_goal: str | None = None
        self._steps = 0  # control steps since the last reset: a row with no source still counts them
        self._last_action = np.zeros(7)
        inner = env.unwrapped
        self.task_id = int(getattr(inner, "task_id", -1))
        obs_space = dict(env.observation_space.spaces)
        if not cameras:
            obs_space.pop("pixels", None)
            inner.camera_name = []  # LiberoEnv._format_raw_obs then reads no camera
            obs_space["environment_state"] = spaces.Box(-np.inf, np.inf, (ENV_STATE_DIM,), np.float64)
        rs = dict(obs_space["robot_state"].spaces) if "robot_state" in obs_space else {}
        rs[STATE_KEY] = spaces.Box(-np.inf, np.inf, (packed_size(N_JOINTS),), np.float64)
        rs[EXTRA_KEY] = spaces.Box(-np.inf, np.inf, (2 + 7,), np.float64)
        obs_space["robot_state"] = spaces.Dict(rs)
        self.observation_space = spaces.Dict(obs_space)

    def _build_without_renderer(self) -> None:
        inner = self.env.unwrapped
        if inner._env is not None:
            return
        from libero.libero.envs.env_wrapper import ControlEnv

        env = ControlEnv(
            bddl_file_name=inner._task_bddl_file, has_renderer=False, has_offscreen_renderer=False,
            use_camera_obs=False, control_freq=inner.control_freq, hard_reset=inner.hard_reset,
        )
        env.reset()
        inner._env = env

    def _augment(self, obs: dict, success: bool) -> dict:
        obs = dict(obs)
        if not self.cameras:
            obs.pop("pixels", None)
        row = None
        if self.source is not None:
            try:
                row = self.source.read_packed()
            except Exception as err:  # noqa: BLE001 - do-no-harm: an unreadable state turns correction off
                self.read_failures += 1
                if self.read_failures == 1:
                    warnings.warn(f"physvla: the state source failed ({err!r}); the corrector passes actions "
                                  "through while it does", RuntimeWarning, stacklevel=2)
        if row is None or row.shape != (packed_size(N_JOINTS),):
            row = np.zeros(packed_size(N_JOINTS))  # valid = 0: the corrector passes through
            row[_F["episode_step"]] = self._steps  # episodes still split where they do
            row[_F["dt"]] = 1.0 / float(getattr(self.env.unwrapped, "control_freq", 20) or 20)
            if self.unsupported_goal is not None:
                row[_F["valid"]] = UNSUPPORTED_GOAL_VALID
        rs = dict(obs.get("robot_state", {}))
        rs[STATE_KEY] = row if self.perception is None else self.perception.apply(row[None])[0]
        rs[EXTRA_KEY] = np.concatenate([[self.task_id, float(success)], self._last_action])
        obs["robot_state"] = rs
        if not self.cameras:  # object xyz, target xyz
            obs["environment_state"] = np.concatenate([row[_OBJ : _OBJ + 3], row[_TGT : _TGT + 3]])
        return obs

    def reset(self, **kwargs):
        from lerobot_physvla.sources.robosuite import RobosuiteStateSource, UnsupportedGoal

        if not self.cameras:
            self._build_without_renderer()
        obs, info = self.env.reset(**kwargs)
        self._steps = 0
        try:  # a hard reset rebuilds LIBERO's model: read it afresh
            self.source = RobosuiteStateSource(self.env.unwrapped._env.env)
            self.source.reset()
        except UnsupportedGoal as e:  # a task outside the model: said once, its rows marked, actions passed
            self.source, self.unsupported_goal = None, e.goal
            if e.goal not in _WARNED_GOALS:
                _WARNED_GOALS.add(e.goal)
                warnings.warn(f"physvla: task {self.task_id} ({getattr(self.env.unwrapped, 'task', '?')}): "
                              f"{str(e).removeprefix('physvla: ')} (counted as unsupported_goal)", RuntimeWarning,
                              stacklevel=2)
            info = {**info, "physvla_unsupported_goal": e.goal}
        except Exception as e:  # noqa: BLE001 - do-no-harm: no state -> the corrector passes through
            self.source = None
            info = {**info, "physvla_state_error": repr(e)}
        self._last_action = np.zeros(7)
        if self.perception is not None:
            self.perception.reset(seed=kwargs.get("seed"))
        return self._augment(obs, False), info

    def step(self, action):
        self._last_action = np.asarray(action, dtype=np.float64).copy()
        obs, reward, terminated, truncated, info = self.env.step(action)
        self._steps += 1
        if self.source is not None:
            self.source.step()
        return self._augment(obs, bool(info.get("is_success", False))), reward, terminated, truncated, info

    def render(self):
        return self.env.render() if self.cameras else _BLANK_FRAME


def _wrapped(make_env, cameras: bool, perception: PerceptionConfig | None = None):
    return PhysVLAStateExport(make_env(), cameras=cameras, perception=perception)


@EnvConfig.register_subclass("libero_physvla")
@dataclass
class LiberoPhysVLAEnvConfig(LiberoEnvConfig):
    """lerobot's `libero` env config plus the PhysVLA state export.

    Attributes:
        cameras: render LIBERO's cameras (as `libero`); false gives a state-only env whose
            observations are robot_state + environment_state (object and target xyz).
        pose_bias_m, pose_noise_m, pose_lag_steps, pose_dropout: the perception model's faults on the
            object's and the target's poses in physvla_state (sources/perception.py PoseFaults: a bias of
            this length per episode (m), noise sigma per axis (m), lag (control steps), the fraction of
            steps missing); all 0: exact. The policy's observation is never touched.
    """

    cameras: bool = True
    pose_bias_m: float = 0.0
    pose_noise_m: float = 0.0
    pose_lag_steps: int = 0
    pose_dropout: float = 0.0

    @property
    def perception(self) -> PerceptionConfig:
        return PerceptionConfig.from_flags(self)

    def __post_init__(self):
        super().__post_init__()
        self.perception  # noqa: B018 - a fault out of range is a clear ValueError now, not in a worker
        if not self.cameras:
            for key in list(self.features):
                if self.features[key].type == FeatureType.VISUAL:
                    del self.features[key]
            self.features["environment_state"] = PolicyFeature(type=FeatureType.ENV, shape=(ENV_STATE_DIM,))
            self.features_map["environment_state"] = OBS_ENV_STATE
            self.features_map = {k: v for k, v in self.features_map.items() if not v.startswith(OBS_IMAGES)}

    def create_envs(self, n_envs: int, use_async_envs: bool = False):
        from lerobot.envs.libero import create_libero_envs

        if self.task is None:
            raise ValueError("libero_physvla requires --env.task (e.g. libero_spatial)")
        with compat.wrapped_libero_env_factories(partial(_wrapped, cameras=self.cameras, perception=self.perception)):
            return create_libero_envs(
                task=self.task, n_envs=n_envs, camera_name=self.camera_name, init_states=self.init_states,
                gym_kwargs=self.gym_kwargs, env_cls=compat.vector_env_class(use_async_envs, n_envs),
                control_mode=self.control_mode, episode_length=self.episode_length,
                camera_name_mapping=self.camera_name_mapping, is_libero_plus=self.is_libero_plus,
            )

    def get_env_processors(self):
        return (
            PolicyProcessorPipeline(steps=[PhysVLAStateCaptureStep(), LiberoProcessorStep()]),
            PolicyProcessorPipeline(steps=[]),
        )


def as_physvla_env(env_cfg):
    """A `libero` env config becomes `libero_physvla` with the same fields; others are returned as is."""
    if type(env_cfg) is LiberoEnvConfig:
        fields = {f.name: getattr(env_cfg, f.name) for f in dataclasses.fields(LiberoEnvConfig) if f.init}
        fields.pop("features", None)
        fields.pop("features_map", None)
        return LiberoPhysVLAEnvConfig(**fields)
    return env_cfg
