"""Config of the `physvla_scripted` policy: the scripted expert, loadable with --policy.path.

It reads only what the state-only `libero_physvla` env gives every policy:
observation.state[:3] (end-effector xyz) and observation.environment_state (object xyz,
target xyz). Failure modes of the paper are injectable and seeded (see experts.ExpertConfig);
`layout` and `expert` (waypoint geometry) fit it to another scene's action layout and objects
(backbones/make_scripted_policy.py --scene lift|lift_plate|fetch_pick_place).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from lerobot.configs.policies import PreTrainedConfig
from lerobot.configs.types import FeatureType, NormalizationMode, PolicyFeature
from lerobot.optim.optimizers import AdamWConfig


@PreTrainedConfig.register_subclass("physvla_scripted")
@dataclass
class PhysVLAScriptedConfig(PreTrainedConfig):
    """Attributes: the failure-mode knobs of experts.ExpertConfig (units there); `layout`, a
    preset of config.LAYOUTS; `expert`, other ExpertConfig fields (geometry, gains, release)."""

    action_noise: float = 0.0
    aim_noise_m: float = 0.0
    place_bias_m: float = 0.0
    premature_close: float = 0.0
    no_decel: bool = False
    noise_stage: str = "all"
    place_bias_units: float = 0.0
    seed: int = 0
    layout: str = "libero_osc_pose"
    expert: dict = field(default_factory=dict)
    normalization_mapping: dict[str, NormalizationMode] = field(
        default_factory=lambda: {
            "STATE": NormalizationMode.IDENTITY,
            "ENV": NormalizationMode.IDENTITY,
            "VISUAL": NormalizationMode.IDENTITY,
            "ACTION": NormalizationMode.IDENTITY,
        }
    )
    input_features: dict[str, PolicyFeature] = field(
        default_factory=lambda: {
            "observation.state": PolicyFeature(type=FeatureType.STATE, shape=(8,)),
            "observation.environment_state": PolicyFeature(type=FeatureType.ENV, shape=(6,)),
        }
    )
    output_features: dict[str, PolicyFeature] = field(
        default_factory=lambda: {"action": PolicyFeature(type=FeatureType.ACTION, shape=(7,))}
    )

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

    def __post_init__(self):
        super().__post_init__()
        from lerobot_physvla.core.config import LAYOUTS

        if self.layout not in LAYOUTS:
            raise ValueError(f"physvla_scripted: unknown layout {self.layout!r}; choose one of {', '.join(LAYOUTS)}")
        dim = LAYOUTS[self.layout].dim
        if self.output_features["action"].shape != (dim,):
            self.output_features = {"action": PolicyFeature(type=FeatureType.ACTION, shape=(dim,))}

    def validate_features(self) -> None:
        if "observation.environment_state" not in self.input_features:
            raise ValueError("physvla_scripted needs observation.environment_state (use --env.cameras=false)")
