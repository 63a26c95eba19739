"""`PhysVLAScriptedPolicy`: one scripted expert per env of the batch, no learned weights."""

from __future__ import annotations

import numpy as np
import torch
from torch import Tensor

from lerobot.policies.pretrained import PreTrainedPolicy

from lerobot_physvla.core.config import LAYOUTS
from lerobot_physvla.sim.experts import ExpertConfig, PickPlaceExpert
from .configuration_physvla_scripted import PhysVLAScriptedConfig


class PhysVLAScriptedPolicy(PreTrainedPolicy):
    config_class = PhysVLAScriptedConfig
    name = "physvla_scripted"

    def __init__(self, config: PhysVLAScriptedConfig, **kwargs):
        super().__init__(config)
        self.config = config
        self._anchor = torch.nn.Parameter(torch.zeros(1), requires_grad=False)  # a device / dtype anchor
        self.experts: list[PickPlaceExpert] = []
        self._episodes = 0

    def _expert_cfg(self, index: int) -> ExpertConfig:
        c = self.config
        geometry = {k: tuple(v) if isinstance(v, list) else v for k, v in c.expert.items()}  # JSON lists -> tuples
        return ExpertConfig(**{**geometry, "action_noise": c.action_noise, "aim_noise_m": c.aim_noise_m,
                               "place_bias_m": c.place_bias_m, "premature_close": c.premature_close,
                               "no_decel": c.no_decel, "noise_stage": c.noise_stage,
                               "place_bias_units": c.place_bias_units, "seed": c.seed + index})

    def reset(self):
        """New rollout batch: fresh experts (seeded per episode, so runs are reproducible)."""
        self.experts = []

    def get_optim_params(self) -> dict:
        return {}

    def forward(self, batch: dict[str, Tensor]):
        raise NotImplementedError("physvla_scripted is not trainable")

    @torch.no_grad()
    def predict_action_chunk(self, batch: dict[str, Tensor], **kwargs) -> Tensor:
        return self.select_action(batch)[:, None]

    @torch.no_grad()
    def select_action(self, batch: dict[str, Tensor], **kwargs) -> Tensor:
        state = batch["observation.state"].detach().cpu().double().numpy()
        scene = batch["observation.environment_state"].detach().cpu().double().numpy()
        b = state.shape[0]
        while len(self.experts) < b:
            self.experts.append(PickPlaceExpert(LAYOUTS[self.config.layout], cfg=self._expert_cfg(self._episodes)))
            self._episodes += 1
        out = np.stack([self.experts[i].act(state[i, :3], scene[i, :3], scene[i, 3:6]) for i in range(b)])
        return torch.from_numpy(out).to(device=self._anchor.device, dtype=torch.float32)
