"""Config of the `physvla_metaworld_scripted` policy: each MetaWorld task's own scripted policy, loadable with
--policy.path, so that lerobot-eval runs MetaWorld's 50 experts (a suite of competent policies nobody here wrote).

It reads what `--env.type=metaworld_physvla --env.cameras=false --env.raw_obs=true` gives every policy:
observation.environment_state = MetaWorld's own 39-D observation (hand xyz, finger opening, the objects' poses, the
previous frame's 18, the goal), exactly what `metaworld.policies` reads. The task comes from `task` (a MetaWorld
task name) or, where it is "", from the batch's task description (lerobot's TASK_DESCRIPTIONS), so one checkpoint
serves `--env.task=a,b,...`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from lerobot.configs.policies import PreTrainedConfig
from lerobot.configs.types import FeatureType, NormalizationMode, PolicyFeature
from lerobot.optim.optimizers import AdamWConfig

RAW_OBS_DIM = 39  # MetaWorld v3's observation


@PreTrainedConfig.register_subclass("physvla_metaworld_scripted")
@dataclass
class PhysVLAMetaworldScriptedConfig(PreTrainedConfig):
    """Attributes:
        task: the MetaWorld task whose policy runs ("pick-place-v3"; "" = each env's own, from the batch's task
            description).
    """

    task: str = ""
    normalization_mapping: dict[str, NormalizationMode] = field(
        default_factory=lambda: {"STATE": NormalizationMode.IDENTITY, "ENV": NormalizationMode.IDENTITY,
                                 "VISUAL": NormalizationMode.IDENTITY, "ACTION": NormalizationMode.IDENTITY})
    input_features: dict[str, PolicyFeature] = field(
        default_factory=lambda: {"observation.environment_state": PolicyFeature(type=FeatureType.ENV,
                                                                                shape=(RAW_OBS_DIM,))})
    output_features: dict[str, PolicyFeature] = field(
        default_factory=lambda: {"action": PolicyFeature(type=FeatureType.ACTION, shape=(4,))})

    @property
    def observation_delta_indices(self) -> None:
        return None

    @property
    def action_delta_indices(self) -> None:
        return None

    @property
    def reward_delta_indices(self) -> None:
        return None

    def get_optimizer_preset(self) -> AdamWConfig:
        return AdamWConfig(lr=0.0)

    def get_scheduler_preset(self) -> None:
        return None

    def validate_features(self) -> None:
        env = self.input_features.get("observation.environment_state")
        if env is None or tuple(env.shape) != (RAW_OBS_DIM,):
            raise ValueError("physvla_metaworld_scripted reads MetaWorld's 39-D observation: run it with "
                             "--env.type=metaworld_physvla --env.cameras=false --env.raw_obs=true")
