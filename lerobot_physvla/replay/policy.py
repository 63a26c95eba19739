"""A LeRobot policy checkpoint acting on recorded (or live) state observations, open loop.

`LeRobotPolicy` loads a checkpoint directory (`--policy.path`) with its saved pre/post
processors, as lerobot-eval does, and maps one observation dict to one action. `compare` runs
it over the recorded observations of each episode and scores its actions against the recorded
ones, raw and corrected (the corrector fed the recorded state), per action channel.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np


class LeRobotPolicy:
    """A LeRobot policy checkpoint on CPU, one env.

    Attributes:
        path: the checkpoint directory (config.json, model.safetensors, processor files).
        policy: the PreTrainedPolicy (eval mode).
        preprocess, postprocess: its saved processor pipelines.
    """

    def __init__(self, path: str | Path):
        import torch

        from lerobot.configs.policies import PreTrainedConfig
        from lerobot.policies.factory import get_policy_class, make_pre_post_processors
        from lerobot.utils.import_utils import register_third_party_plugins

        self.path = Path(path)
        if not (self.path / "config.json").is_file():
            raise ValueError(f"physvla: --policy.path={path} holds no LeRobot checkpoint (no config.json there)")
        torch.set_num_threads(1)
        register_third_party_plugins()  # policy types of installed plugins (as lerobot's scripts do)
        cfg = PreTrainedConfig.from_pretrained(str(self.path))
        cfg.device = "cpu"
        self.policy = get_policy_class(cfg.type).from_pretrained(str(self.path), config=cfg)
        self.policy.eval()
        # as lerobot-eval does: the saved pipeline names the device it was trained on (a GPU-trained
        # checkpoint says cuda); here it runs on the CPU
        self.preprocess, self.postprocess = make_pre_post_processors(
            cfg, pretrained_path=str(self.path), preprocessor_overrides={"device_processor": {"device": "cpu"}})
        self.input_keys = [k for k in cfg.input_features]
        self._torch = torch

    def reset(self, seed: int = 0) -> None:
        self._torch.manual_seed(seed)  # sampling noise of generative policies, matched per episode
        self.policy.reset()

    def act(self, obs: dict[str, np.ndarray], task: str) -> np.ndarray:
        """The policy's action (A,) float64 for one observation {feature: (d,) array}."""
        torch = self._torch
        batch = {k: torch.from_numpy(np.asarray(v, dtype=np.float32))[None] for k, v in obs.items()}
        batch["task"] = [task]
        with torch.inference_mode():
            action = self.postprocess(self.policy.select_action(self.preprocess(batch)))
        return action[0].double().cpu().numpy()


def policy_actions(policy: LeRobotPolicy, episode) -> np.ndarray:
    """(T, A) the policy's actions on an episode's recorded observations, from a fresh reset."""
    missing = [k for k in policy.input_keys if k not in episode.obs]
    if missing:
        raise ValueError(f"physvla: the policy reads {missing}, which the dataset does not have; "
                         f"it has {sorted(episode.obs)}")
    policy.reset(episode.index)
    keys = policy.input_keys
    return np.stack([policy.act({k: episode.obs[k][t] for k in keys}, episode.task) for t in range(episode.frames)])


def per_channel_mse(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(A,) mean squared error per action channel."""
    return ((np.asarray(a, float) - np.asarray(b, float)) ** 2).mean(axis=0)


def replay_policy(data, policy_path: str, cfg, column_state=None, progress: bool = True) -> list[dict]:
    """Per episode: the policy's actions on the recorded observations against the recorded actions
    (per-channel MSE), raw and after the corrector (fed the recorded states)."""
    from tqdm import tqdm

    from lerobot_physvla.replay.offline import correct_shard, effective_config, episode_states

    policy = LeRobotPolicy(policy_path)
    cfg, _ = effective_config(cfg, data)
    out = []
    for ep in tqdm(data.episodes, desc="policy replay", unit="episode", disable=not progress):
        pred = policy_actions(policy, ep)
        if pred.shape[1] != ep.actions.shape[1]:
            raise ValueError(f"physvla: the policy outputs {pred.shape[1]} action channels, the dataset has "
                             f"{ep.actions.shape[1]}")
        res = correct_shard(cfg.to_dict(), [(ep.index, pred, episode_states(data, ep, column_state))])[0]
        corrected = res["corrected"]
        raw_mse, cor_mse = per_channel_mse(pred, ep.actions), per_channel_mse(corrected, ep.actions)
        out.append({"episode": ep.index, "task": ep.task, "frames": ep.frames,
                    "mse_raw": raw_mse.tolist(), "mse_corrected": cor_mse.tolist(),
                    "mse_raw_mean": float(raw_mse.mean()), "mse_corrected_mean": float(cor_mse.mean()),
                    "_arrays": {"raw": pred, "corrected": corrected, "recorded": ep.actions, "phase": res["phase"],
                                "r_el": res["r_el"]}})
    return out
