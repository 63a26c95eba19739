"""Env type `so101_physvla`: lerobot-env-so101's `so101` env plus the physical-state export.

    lerobot-eval --env.type=so101_physvla --env.task=SO101PickPlace-v0 ...
    lerobot-eval --env.type=so101 --env.task=SO101PickPlace-v0 --policy.postprocess=physvla   (becomes the above)

Each sub-env (in the main process or an async worker) is what `so101` builds, `gym.make(gym_id, **gym_kwargs)` with
gym_id "lerobot_env_so101/<task>" (the package's own `package_name`), inside `SO101StateExport`, a gym.Wrapper
that adds to every observation
    robot_state["physvla_state"]  the packed PhysState of this env (sources/so101.py)
    robot_state["physvla_extra"]  [task_id, is_success, the action executed last step (4)]
and to every step's info `is_success` (the env's own `succeed`, under the name lerobot-eval counts). agent_pos,
environment_state and pixels stay what the so101 env gives the policy, and the wrapper adds no `task` attribute
(the policy's task string stays ""). The env preprocessor puts `PhysVLAStateCaptureStep` first, which takes
robot_state out before the policy sees it. The vector envs are as `so101`'s (same-step autoreset, forkserver
workers for async); a task is its own group in lerobot-eval, ids counting over `--env.task`'s comma-separated tasks.

Two things `so101` gets wrong for the pick-and-place task in lerobot-env-so101 0.4.0, fixed here: its gym_kwargs
pass `reward_type`, which `SO101PickPlaceGymEnv` does not take (gym.make raises), and its features declare a 3-D
environment_state where that task gives 6 (the block, then the goal). Tasks outside the corrector's model
(sources/so101.py UNSUPPORTED: the pick-cube lift) export valid = -1 rows: the corrector passes them through,
counted as unsupported_goal with the reason.

The corrector's configuration follows the env (`physvla_defaults`: the so101 action layout at this config's
action_scale, core/config.py so101_layout; Branch B's task_space weighting, since joint_diag refuses a 5-joint
arm on a 4-D action) where no --physvla.<field> names its own.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from functools import partial

import gymnasium as gym

from lerobot.configs.types import FeatureType, PolicyFeature
from lerobot.envs.configs import EnvConfig
from lerobot.processor import PolicyProcessorPipeline
from lerobot.utils.constants import OBS_ENV_STATE, OBS_IMAGES
from lerobot_env_so101.configuration_so101 import SO101Env as SO101EnvConfig

from lerobot_physvla.core.config import so101_layout
from lerobot_physvla.envs.state_export import StateExport
from lerobot_physvla.processor.physvla_processor import PhysVLAStateCaptureStep

N_JOINTS = 5  # the SO-101's arm
ACTION_DIM = 4  # dx, dy, dz, grasp
PICK_PLACE = "SO101PickPlace-v0"
PICK_PLACE_ENV_STATE_DIM = 6  # block xyz, goal xyz


class SO101StateExport(StateExport):
    """Adds the physical state of one lerobot-env-so101 sub-env to its observations (see module docstring).

    Attributes:
        task_id: the task's id, as lerobot-eval numbers it (exported in physvla_extra).
        task_name: the task, e.g. "SO101PickPlace-v0" (not `task`: lerobot-eval would hand it to the policy).
        read_failures: state reads that raised (those steps export an invalid state: no correction).
        unsupported_goal: the task and why it is outside what the corrector models; its rows export valid = -1 and
            pass through as unsupported_goal.
    """

    def __init__(self, env, task_id: int = 0, task_name: str = ""):
        super().__init__(env, N_JOINTS, ACTION_DIM, task_id)
        self.task_name = str(task_name)
        self._bound = False  # the env keeps one model for its life: the source is built at the first reset
        self.observation_space = self._state_spaces(dict(env.observation_space.spaces))

    def control_dt(self) -> float:
        return float(getattr(self.env.unwrapped, "control_dt", 0.1))

    def _augment(self, obs: dict, success: bool) -> dict:
        return self._export(obs, success, self._read_row())

    def _bind(self) -> None:
        """The state source of the task env (once: it keeps one model and data for its life)."""
        from lerobot_physvla.sources.robosuite import UnsupportedGoal
        from lerobot_physvla.sources.so101 import SO101StateSource

        if self._bound:
            return
        self._bound = True
        try:
            self.source = SO101StateSource(self.env.unwrapped, self.task_name or None)
        except UnsupportedGoal as e:  # a task outside the model: said once, its rows marked, actions passed
            self._unsupported(e.goal, f"physvla: task {self.task_id} ({self.task_name}): unsupported_goal: {e.goal}; "
                                      "its actions pass through unchanged (counted as unsupported_goal)")
        except Exception as e:  # noqa: BLE001 - do-no-harm: no state -> the corrector passes through
            self._no_source(e, "SO-101")

    def reset(self, **kwargs):
        obs, info = self.env.reset(**kwargs)
        self._begin_episode(kwargs.get("seed"))
        self._bind()
        if self.unsupported_goal is not None:
            info = {**info, "physvla_unsupported_goal": self.unsupported_goal}
        if self.source is not None:
            self.source.reset()
        return self._augment(obs, False), info

    def step(self, action):
        self._executed(action)
        obs, reward, terminated, truncated, info = self.env.step(action)
        self._steps += 1
        if self.source is not None:
            self.source.step()
        success = bool(info.get("succeed", False))
        info = {**info, "is_success": success}
        return self._augment(obs, success), reward, terminated, truncated, info


def _make_env(gym_id: str, gym_kwargs: dict, disable_env_checker: bool, task_id: int,
              task_name: str) -> SO101StateExport:
    import lerobot_env_so101  # noqa: F401 - registers the gym ids (in an async worker too)

    env = gym.make(gym_id, disable_env_checker=disable_env_checker, **gym_kwargs)
    return SO101StateExport(env, task_id=task_id, task_name=task_name)


@EnvConfig.register_subclass("so101_physvla")
@dataclass
class SO101PhysVLAEnvConfig(SO101EnvConfig):
    """lerobot-env-so101's `so101` env config plus the PhysVLA state export (module docstring).

    Its features follow the task (SO101PickPlace-v0: a 6-D environment_state; with image_obs, pixels/front in
    place of environment_state, as the env gives them). `physvla_defaults`: the corrector's fields this env needs,
    applied where the flags set none (scripts/lerobot_physvla_eval.py for_env).
    """

    def __post_init__(self):
        tasks = self.tasks
        if not tasks:
            raise ValueError("so101_physvla requires --env.task (e.g. SO101PickPlace-v0)")
        if self.image_obs:  # the env replaces environment_state by a camera view
            self.features.pop("environment_state", None)
            self.features_map.pop("environment_state", None)
            self.features["pixels/front"] = PolicyFeature(type=FeatureType.VISUAL, shape=(128, 128, 3))
            self.features_map["pixels/front"] = f"{OBS_IMAGES}.front"
        elif tasks[0] == PICK_PLACE:
            self.features["environment_state"] = PolicyFeature(type=FeatureType.ENV,
                                                               shape=(PICK_PLACE_ENV_STATE_DIM,))
            self.features_map["environment_state"] = OBS_ENV_STATE

    @property
    def tasks(self) -> list[str]:
        return [t.strip() for t in str(self.task or "").split(",") if t.strip()]

    @property
    def physvla_defaults(self) -> dict:
        """The so101 action layout at this env's action_scale, and Branch B's task_space weighting."""
        return {"layout": so101_layout(self.action_scale), "weighting": "task_space"}

    @property
    def horizon(self) -> int:
        """The rollout's horizon, control steps (the TimeLimit gym.make puts on each sub-env)."""
        return int(self.episode_length)

    def gym_kwargs_for(self, task: str) -> dict:
        """`so101`'s gym_kwargs for one task, less what its env does not take (the pick-and-place env has no
        reward_type: its reward is its success)."""
        kwargs = dict(self.gym_kwargs)
        if task == PICK_PLACE:
            kwargs.pop("reward_type", None)
        return kwargs

    def create_envs(self, n_envs: int, use_async_envs: bool = False):
        """{task: {task id: vector env}}, each vector env built as `so101` builds its one (EnvConfig.create_envs:
        gym.make(gym_id), same-step autoreset, forkserver workers for async), each sub-env wrapped."""
        import lerobot_env_so101  # noqa: F401 - registers the gym ids

        if not isinstance(n_envs, int) or n_envs <= 0:
            raise ValueError(f"n_envs must be a positive int; got {n_envs}.")
        env_cls = gym.vector.AsyncVectorEnv if (use_async_envs and n_envs > 1) else gym.vector.SyncVectorEnv
        extra: dict = {"context": "forkserver"} if env_cls is gym.vector.AsyncVectorEnv else {}
        out: dict[str, dict[int, object]] = {}
        for tid, task in enumerate(self.tasks):
            gym_id = f"{self.package_name}/{task}"
            if gym_id not in gym.registry:
                raise gym.error.NameNotFound(f"Environment '{gym_id}' is not registered by '{self.package_name}'.")
            fns = [partial(_make_env, gym_id, self.gym_kwargs_for(task), self.disable_env_checker, tid, task)
                   for _ in range(n_envs)]
            out[task] = {tid: env_cls(fns, autoreset_mode=gym.vector.AutoresetMode.SAME_STEP, **extra)}
        return out

    def get_env_processors(self):
        return PolicyProcessorPipeline(steps=[PhysVLAStateCaptureStep()]), PolicyProcessorPipeline(steps=[])


def as_so101_physvla_env(env_cfg, given=()):
    """An `so101` env config becomes `so101_physvla` with the same fields (its features follow the task); others
    are returned as is. `given` (the --env.<name> flags set) is accepted for the other adapters' signature."""
    if type(env_cfg) is SO101EnvConfig:
        fields = {f.name: getattr(env_cfg, f.name) for f in dataclasses.fields(SO101EnvConfig) if f.init}
        fields.pop("features", None)
        fields.pop("features_map", None)
        return SO101PhysVLAEnvConfig(**fields)
    return env_cfg
