"""Env type `libero_physvla`: lerobot's LIBERO env plus the physical-state export, optionally camera-free.

    lerobot-eval --env.type=libero_physvla --env.task=libero_spatial [--env.cameras=false] ...
    lerobot-eval --env.type=libero_physvla --env.task=libero_object_swap ...   # a LIBERO-PRO suite (libero_pro.py)

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
from dataclasses import dataclass
from functools import partial

import numpy as np
from gymnasium import spaces

from lerobot.configs.types import FeatureType, PolicyFeature
from lerobot.envs.configs import EnvConfig
from lerobot.envs.configs import LiberoEnv as LiberoEnvConfig
from lerobot.processor import PolicyProcessorPipeline
from lerobot.processor.env_processor import LiberoProcessorStep
from lerobot.utils.constants import OBS_ENV_STATE, OBS_IMAGES

from lerobot_physvla import compat
from lerobot_physvla.core.state import field_offsets
from lerobot_physvla.envs.state_export import StateExport
from lerobot_physvla.processor.physvla_processor import PhysVLAStateCaptureStep
from lerobot_physvla.sources.perception import PerceptionConfig

N_JOINTS = 7  # the Panda of LIBERO
ENV_STATE_DIM = 6  # object xyz, target xyz
_BLANK_FRAME = np.zeros((64, 64, 3), np.uint8)  # what render() shows with cameras off
_F = field_offsets(N_JOINTS)
_OBJ, _TGT = _F["obj_pos"], _F["target_pos"]


class PhysVLAStateExport(StateExport):
    """Adds the physical state of one LIBERO sub-env to its observations (see module docstring and
    envs/state_export.py for what every env type's export shares).

    Attributes:
        cameras: False builds LIBERO with no renderer and returns no pixels.
        task_id: the LIBERO task id (exported in physvla_extra).
        read_failures: state reads that raised (those steps export an invalid state: no correction).
        unsupported_goal: the task's goal in words where it is outside what the corrector models (no On / In
            predicate: a drawer, a stove, a push); its rows export valid = -1 and pass through as unsupported_goal.
        perception: the perception model between the simulator and physvla_state (None: exact poses).
    """

    def __init__(self, env, cameras: bool = True, perception: PerceptionConfig | None = None):
        super().__init__(env, N_JOINTS, 7, int(getattr(env.unwrapped, "task_id", -1)), perception)
        self.cameras = cameras
        inner = env.unwrapped
        obs_space = dict(env.observation_space.spaces)
        if not cameras:
            obs_space.pop("pixels", None)
            inner.camera_name = []  # LiberoEnv._format_raw_obs then reads no camera
            obs_space["environment_state"] = spaces.Box(-np.inf, np.inf, (ENV_STATE_DIM,), np.float64)
        self.observation_space = self._state_spaces(obs_space)

    def control_dt(self) -> float:
        return 1.0 / float(getattr(self.env.unwrapped, "control_freq", 20) or 20)

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
        row = self._read_row()
        obs = self._export(obs, success, row)
        if not self.cameras:  # object xyz, target xyz
            obs["environment_state"] = np.concatenate([row[_OBJ : _OBJ + 3], row[_TGT : _TGT + 3]])
        return obs

    def reset(self, **kwargs):
        from lerobot_physvla.sources.robosuite import RobosuiteStateSource, UnsupportedGoal

        if not self.cameras:
            self._build_without_renderer()
        obs, info = self.env.reset(**kwargs)
        self._begin_episode(kwargs.get("seed"))
        try:  # a hard reset rebuilds LIBERO's model: read it afresh
            self.source = RobosuiteStateSource(self.env.unwrapped._env.env)
            self.source.reset()
        except UnsupportedGoal as e:  # a task outside the model: said once, its rows marked, actions passed
            self.source = None
            self._unsupported(e.goal, f"physvla: task {self.task_id} ({getattr(self.env.unwrapped, 'task', '?')}): "
                                      f"{str(e).removeprefix('physvla: ')} (counted as unsupported_goal)")
            info = {**info, "physvla_unsupported_goal": e.goal}
        except Exception as e:  # noqa: BLE001 - do-no-harm: no state -> the corrector passes through
            self.source = None
            info = {**info, "physvla_state_error": repr(e)}
        return self._augment(obs, False), info

    def step(self, action):
        self._executed(action)
        obs, reward, terminated, truncated, info = self.env.step(action)
        self._steps += 1
        if self.source is not None:
            self.source.step()
        return self._augment(obs, bool(info.get("is_success", False))), reward, terminated, truncated, info

    def render(self):
        return self.env.render() if self.cameras else _BLANK_FRAME


def _wrapped(make_env, cameras: bool, perception: PerceptionConfig | None = None, first_init_state: int = 0):
    env = make_env()
    env.init_state_id += first_init_state  # lerobot's order (sub-env i, episode k: i + k * n_envs), shifted
    return PhysVLAStateExport(env, cameras=cameras, perception=perception)


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
        first_init_state: the init state sub-env 0's first episode starts from (lerobot's order shifted: sub-env i,
            episode k starts from first_init_state + i + k * n_envs, modulo the task's init states); 0 as `libero`.
    """

    cameras: bool = True
    first_init_state: int = 0
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
        if not (isinstance(self.first_init_state, int) and self.first_init_state >= 0):
            raise ValueError(f"libero_physvla: first_init_state must be an init state index >= 0, got "
                             f"{self.first_init_state!r}")
        if not self.cameras:
            for key in list(self.features):
                if self.features[key].type == FeatureType.VISUAL:
                    del self.features[key]
            self.features["environment_state"] = PolicyFeature(type=FeatureType.ENV, shape=(ENV_STATE_DIM,))
            self.features_map["environment_state"] = OBS_ENV_STATE
            self.features_map = {k: v for k, v in self.features_map.items() if not v.startswith(OBS_IMAGES)}

    def create_envs(self, n_envs: int, use_async_envs: bool = False):
        from lerobot.envs.libero import create_libero_envs

        from lerobot_physvla.envs import libero_pro

        if self.task is None:
            raise ValueError("libero_physvla requires --env.task (e.g. libero_spatial)")
        # LIBERO-PRO's suites (envs/libero_pro.py) resolve here too; the state export wraps every sub-env
        with (compat.extra_libero_suites(libero_pro.resolve, libero_pro.make_env_fns),
              compat.wrapped_libero_env_factories(partial(_wrapped, cameras=self.cameras, perception=self.perception,
                                                          first_init_state=self.first_init_state))):
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
