"""Make a LeRobot policy with random weights through lerobot's own factory, saved locally.

    .venv/bin/python backbones/make_random_policy.py OUT_DIR [--type act|diffusion] [--inputs state|image|so101|panda]

--inputs state (default): what the `libero_physvla` env gives with --env.cameras=false,
observation.state (8: eef xyz, axis-angle, 2 finger joints) and observation.environment_state
(6: object xyz, target xyz). --inputs image: observation.state and LIBERO's agent-view camera
(observation.images.image, 3x360x360), for plain `--env.type=libero`. Output: the 7-D action.
--inputs so101: the simulated SO-101 (robot type physvla_sim_so101, blank_camera=true): its six
motor positions and its blank camera, the 6-D joint-target action, for lerobot-rollout. --inputs
panda: the same for the simulated Panda (physvla_sim_panda): 7 joints and the gripper, 8-D action. Normalisation stats are identity
(mean 0, std 1; min -1, max 1), so the processors are complete. Used by the tests and docs to
exercise the real lerobot-eval path without any hub download.
"""

from __future__ import annotations

import argparse

import torch

from lerobot.configs.types import FeatureType, PolicyFeature
from lerobot.envs.configs import LiberoEnv
from lerobot.policies.factory import make_policy, make_policy_config, make_pre_post_processors

INPUTS = {
    "state": {
        "observation.state": PolicyFeature(type=FeatureType.STATE, shape=(8,)),
        "observation.environment_state": PolicyFeature(type=FeatureType.ENV, shape=(6,)),
    },
    # the simulated SO-101 (robot type physvla_sim_so101 with blank_camera=true): 6 motor positions
    # (lerobot-rollout routes only ".pos" readings to the policy) and its blank 8x8 camera (ACT
    # needs an image or an environment state)
    "so101": {
        "observation.state": PolicyFeature(type=FeatureType.STATE, shape=(6,)),
        "observation.images.front": PolicyFeature(type=FeatureType.VISUAL, shape=(3, 8, 8)),
    },
    "panda": {  # the simulated Panda (physvla_sim_panda, blank_camera=true): 7 joints and the gripper
        "observation.state": PolicyFeature(type=FeatureType.STATE, shape=(8,)),
        "observation.images.front": PolicyFeature(type=FeatureType.VISUAL, shape=(3, 8, 8)),
    },
    "image": {
        "observation.state": PolicyFeature(type=FeatureType.STATE, shape=(8,)),
        "observation.images.image": PolicyFeature(type=FeatureType.VISUAL, shape=(3, 360, 360)),
    },
}
SMALL = {
    "act": dict(chunk_size=10, n_action_steps=10, dim_model=64, dim_feedforward=128, n_heads=4,
                n_encoder_layers=1, n_decoder_layers=1, use_vae=False, pretrained_backbone_weights=None),
    "diffusion": dict(n_obs_steps=2, horizon=16, n_action_steps=8, down_dims=(32, 64), num_inference_steps=4,
                      pretrained_backbone_weights=None),
}


ACTION_DIM = {"state": 7, "image": 7, "so101": 6, "panda": 8}
ROBOTS = ("so101", "panda")  # inputs of a simulated robot: no env config, the joint targets are the action


def identity_stats(inputs: str = "state") -> dict:
    stats = {}
    dims = {k: f.shape[0] for k, f in INPUTS[inputs].items() if f.type != FeatureType.VISUAL}
    for key, dim in (*dims.items(), ("action", ACTION_DIM[inputs])):
        stats[key] = {"mean": torch.zeros(dim), "std": torch.ones(dim), "min": -torch.ones(dim), "max": torch.ones(dim)}
    shape = (3, 1, 1)
    for key in (k for k, f in INPUTS[inputs].items() if f.type == FeatureType.VISUAL and k != "observation.images.image"):
        stats[key] = {"mean": torch.zeros(shape), "std": torch.ones(shape), "min": torch.zeros(shape),
                      "max": torch.ones(shape)}
    stats["observation.images.image"] = {"mean": torch.zeros(shape), "std": torch.ones(shape),
                                         "min": torch.zeros(shape), "max": torch.ones(shape)}
    return stats


def make(out, type: str = "act", inputs: str = "state", seed: int = 0) -> None:
    """Save a random-weight `type` policy for `inputs` (INPUTS) with identity statistics to `out`."""
    torch.manual_seed(seed)
    cfg = make_policy_config(type, device="cpu", input_features=dict(INPUTS[inputs]), **SMALL[type])
    if inputs in ROBOTS:  # no env config: the robot's joint targets are the action
        from lerobot.policies.factory import get_policy_class

        cfg.output_features = {"action": PolicyFeature(type=FeatureType.ACTION, shape=(ACTION_DIM[inputs],))}
        policy = get_policy_class(cfg.type)(cfg)
    else:
        policy = make_policy(cfg, env_cfg=LiberoEnv(task="libero_spatial"))
    pre, post = make_pre_post_processors(cfg, dataset_stats=identity_stats(inputs))
    policy.save_pretrained(out)
    pre.save_pretrained(out)
    post.save_pretrained(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out")
    ap.add_argument("--type", default="act", choices=sorted(SMALL))
    ap.add_argument("--inputs", default="state", choices=sorted(INPUTS))
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    make(args.out, args.type, args.inputs, args.seed)
    print(f"saved a random-weight {args.type} policy to {args.out}")


if __name__ == "__main__":
    main()
