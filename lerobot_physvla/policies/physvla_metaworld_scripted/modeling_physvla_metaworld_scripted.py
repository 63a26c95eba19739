"""`PhysVLAMetaworldScriptedPolicy`: each env's MetaWorld task policy (`metaworld.policies`), no learned weights."""

from __future__ import annotations

import warnings

import numpy as np
import torch
from torch import Tensor

from lerobot.policies.pretrained import PreTrainedPolicy

from lerobot_physvla.sim.metaworld_expert import make_policy
from .configuration_physvla_metaworld_scripted import RAW_OBS_DIM, PhysVLAMetaworldScriptedConfig


def task_of_description(words: str) -> str:
    """The MetaWorld task whose lerobot description is `words` (lerobot's TASK_DESCRIPTIONS); ValueError otherwise."""
    from lerobot.envs.metaworld import TASK_DESCRIPTIONS

    names = [t for t, d in TASK_DESCRIPTIONS.items() if d == words]
    if len(names) != 1:
        raise ValueError(f"physvla_metaworld_scripted: no single MetaWorld task is described as {words!r}; set "
                         "--policy.task=<a MetaWorld task name>")
    return names[0]


class PhysVLAMetaworldScriptedPolicy(PreTrainedPolicy):
    config_class = PhysVLAMetaworldScriptedConfig
    name = "physvla_metaworld_scripted"

    def __init__(self, config: PhysVLAMetaworldScriptedConfig, **kwargs):
        super().__init__(config)
        self.config = config
        self._anchor = torch.nn.Parameter(torch.zeros(1), requires_grad=False)  # a device / dtype anchor
        self._policies: dict[str, object] = {}

    def reset(self):
        """MetaWorld's policies are memoryless: nothing to reset."""

    def get_optim_params(self) -> dict:
        return {}

    def forward(self, batch: dict[str, Tensor]):
        raise NotImplementedError("physvla_metaworld_scripted is not trainable")

    @torch.no_grad()
    def predict_action_chunk(self, batch: dict[str, Tensor], **kwargs) -> Tensor:
        return self.select_action(batch)[:, None]

    def _policy(self, task: str):
        if task not in self._policies:
            self._policies[task] = make_policy(task)
        return self._policies[task]

    @torch.no_grad()
    def select_action(self, batch: dict[str, Tensor], **kwargs) -> Tensor:
        obs = batch["observation.environment_state"].detach().cpu().double().numpy()
        if obs.shape[-1] != RAW_OBS_DIM:
            raise ValueError(f"physvla_metaworld_scripted reads MetaWorld's 39-D observation, got {obs.shape[-1]}: run "
                             "it with --env.type=metaworld_physvla --env.cameras=false --env.raw_obs=true")
        words = batch.get("task") or [""] * obs.shape[0]
        out = []
        for i in range(obs.shape[0]):
            task = self.config.task or task_of_description(words[i])
            with warnings.catch_warnings():  # metaworld's move() warns whenever its gain saturates the command
                warnings.simplefilter("ignore")
                a = np.asarray(self._policy(task).get_action(obs[i]), dtype=np.float64)
            out.append(np.clip(a, -1.0, 1.0))
        return torch.from_numpy(np.stack(out)).to(device=self._anchor.device, dtype=torch.float32)
